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


@pytest.mark.skipif(not peers.installed("gtsam"), reason="gtsam not installed here")
def test_isam2_failing_at_a_step_is_a_row_that_says_where(monkeypatch, capsys):
    """GTSAM's ISAM2 throws on some data (mit, with its default Cholesky: an indeterminate system at step
    224): the row names the step and GTSAM's first paragraph, and the other rows still run."""
    import gtsam

    real = gtsam.ISAM2

    class Failing:
        def __init__(self, params):
            self.isam, self.steps = real(params), 0

        def update(self, factors, values):
            self.steps += 1
            if self.steps == 5:
                raise RuntimeError("\nIndeterminate linear system detected while working near variable\n4 (Symbol: 4)."
                                   "\n\nThrown when a linear system is ill-posed.")
            return self.isam.update(factors, values)

        def __getattr__(self, name):
            return getattr(self.isam, name)

    monkeypatch.setattr(gtsam, "ISAM2", Failing)
    assert main(["online", "manhattan:12", "--no-batch"]) == 0
    out = capsys.readouterr().out
    assert ("GTSAM ISAM2                 ISAM2's update failed at step 4 of 12: Indeterminate linear system "
            "detected while working near variable 4 (Symbol: 4).") in out
    assert "ours (incremental)              12" in out


def test_the_minimum_is_the_lower_of_lm_from_the_file_and_ours_iterated():
    """mit: LM from the file's poses stops at a local minimum (526.3) far above the one the online estimate,
    iterated, reaches (41.16); the rows are compared with the lower, and the line says which it is."""
    row = online.OnlineRow("ours (incremental)", np.full(3, 1e-3), 1.0, 2.0, 41.5)
    low = online.format_table({"rows": [row], "minimum": 41.0, "from_file": 526.0, "iterated": 41.0})
    assert "+1.22e-02" in low and "minimum: chi2 41.000000, ours iterated to convergence" in low
    assert "stops at 526.000000, a local minimum above it" in low
    same = online.format_table({"rows": [row], "minimum": 41.0, "from_file": 41.0, "iterated": 41.0})
    assert "batch minimum (ours, LM on the whole dataset): chi2 41.000000" in same
    assert "ours / GTSAM ISAM2" not in same


def test_the_ratio_to_isam2_is_of_the_same_run():
    ours = online.OnlineRow("ours (incremental)", np.array([1e-3, 2e-3, 9e-3]), 1.0, 2.0, 41.5)
    isam = online.OnlineRow("GTSAM ISAM2", np.array([1e-3, 1e-3, 2e-3]), 1.0, 2.0, 41.5)
    table = online.format_table({"rows": [ours, isam], "minimum": 41.0, "from_file": 41.0, "iterated": 41.0})
    assert "ours / GTSAM ISAM2, this run: total time 3.00x, median step 2.00x" in table
    failed = online.OnlineRow("GTSAM ISAM2", note="fails at step 224")
    assert "ours / GTSAM ISAM2" not in online.format_table({"rows": [ours, failed], "minimum": 41.0,
                                                            "from_file": 41.0, "iterated": 41.0})


def test_the_breakdown_times_every_function_the_updates_call(capsys):
    assert main(["online", "manhattan:30", "--no-batch", "--breakdown"]) == 0
    out = capsys.readouterr().out
    part = out[out.index("our updates' "):]
    names = [f"{module}.{name}" for module, names in online.SMOOTHER_CALLS.items() for name in names]
    rows = {line.split()[0]: line.split() for line in part.splitlines() if line.split()[0] in names}
    assert set(rows) == set(names)  # each is called on this path
    assert int(rows["orderings.minimum_degree_ordering"][1]) == 30  # one ordering per update
    shares = [int(row[3].rstrip("%")) for row in rows.values()]
    inside = next(line for line in part.splitlines() if line.startswith("all of them"))
    framework = next(line for line in part.splitlines() if line.startswith("the framework"))
    assert abs(int(inside.split()[-1].rstrip("%")) + int(framework.split()[-1].rstrip("%")) - 100) <= 1
    assert abs(sum(shares) - int(inside.split()[-1].rstrip("%"))) <= len(shares)


def test_call_times_counts_calls_and_puts_the_originals_back():
    from course.core.call_times import CallTimes
    from course.core.impl import load

    impl = load("solutions")
    module = impl.module("incremental_update")
    original = module.relinearised_keys
    with CallTimes(impl, {"incremental_update": ("relinearised_keys", "orphan_parents"),
                          "no_such_module": ("f",)}) as times:
        assert module.relinearised_keys is not original
        assert list(module.relinearised_keys([np.zeros(3), np.ones(3)], 0.5)) == [1]
        module.relinearised_keys([np.zeros(2)], 0.5)
    assert module.relinearised_keys is original
    assert [(label, calls) for label, calls, _ in times.rows()] == [("incremental_update.relinearised_keys", 2)]
    assert times.total() > 0
