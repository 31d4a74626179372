"""``python -m course online``: the table, the peers' rows, an unwritten piece as one line."""

import numpy as np
import pytest

from course.app import online
from course.app.cli import main
from course.core import peers


def test_the_table_on_a_small_generated_path(capsys, tmp_path):
    assert main(["online", "manhattan:30", "--every", "10", "--plot", str(tmp_path / "steps.png")]) == 0
    out = capsys.readouterr().out
    assert "batch re-solves every 10 steps" in out
    for label in ("ours (incremental)", "GTSAM ISAM2", "ours batch (Gauss-Newton)", "g2o batch (Gauss-Newton)"):
        assert label in out
    assert "the last update iterated to convergence" in out
    assert (tmp_path / "steps.png").stat().st_size > 0


def test_ours_and_isam2_end_near_the_batch_minimum():
    result = online.compare("manhattan:40", impl="solutions", batches=False)
    rows = {row.label: row for row in result["rows"]}
    minimum = result["minimum"]
    assert rows["ours (incremental)"].chi2 == pytest.approx(minimum, rel=1e-3)
    assert result["iterated"] == pytest.approx(minimum, rel=1e-6)
    assert len(rows["ours (incremental)"].seconds) == 40
    assert np.isfinite(rows["ours (incremental)"].relinearized)
    if peers.installed("gtsam"):
        assert rows["GTSAM ISAM2"].chi2 == pytest.approx(minimum, rel=1e-3)


def test_an_unwritten_piece_is_a_row_not_a_traceback(capsys):
    assert main(["online", "manhattan:12", "--impl", "exercises", "--no-batch"]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if line.startswith("ours (incremental)"))
    assert "not implemented: TODO" in line
    assert "Traceback" not in out


def test_a_3d_graph_loads_as_3d():
    graph, dim = online.load("tinyGrid3D")
    assert dim == 3
    row, iterated, _ = online.run_ours(graph, dim, "solutions")
    assert len(row.seconds) == graph.num_poses
    assert iterated <= row.chi2 * (1 + 1e-9)


def test_the_first_poses_only(capsys):
    assert main(["online", "manhattan:40", "--poses", "12", "--no-batch"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("manhattan:40[:12]: 12 poses")


@pytest.mark.skipif(not peers.installed("gtsam"), reason="gtsam not installed here")
def test_a_3d_graph_runs_against_gtsam_s_isam2(capsys):
    """pose3example (5 poses, ships with gtsam): both rows end within the start's reach of the minimum,
    and iterating ours reaches it."""
    assert main(["online", "pose3example", "--no-batch"]) == 0
    out = capsys.readouterr().out
    rows = {line.split()[0]: line.split() for line in out.splitlines() if line.startswith(("ours (", "GTSAM"))}
    assert rows["ours"][2] == rows["GTSAM"][2] == "5"
    minimum = float(out.split("batch minimum (ours, LM on the whole dataset): chi2 ")[1].split()[0])
    assert float(rows["GTSAM"][-2]) >= minimum * (1 - 1e-9)
    iterated = float(out.split("the last update iterated to convergence: chi2 ")[1].split()[0])
    assert abs(iterated - minimum) <= 1e-6 * minimum
