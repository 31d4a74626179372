"""Chapter 3b's lesson (``notebooks/chapter3b_initialisation.py``): its helpers
(``course.notebook_helpers.chapter3b``) and what its executed cells show (quick setting, slow)."""

import re

import numpy as np
import pytest
from test_lesson_3 import _execute, _questions, chapter_1_written  # noqa: F401 (a fixture)

from course.core.trace import RunResult
from course.geometry import se2
from course.notebook_helpers import chapter3b
from course.notebook_helpers.common import initialiser_table
from course.problems.posegraph import dataset as datasets
from notebooks import build


@pytest.fixture(scope="module")
def graph():
    return datasets.load_dataset("manhattan:200")


# ---------------------------------------------------------------- the helpers


def test_drifted_keeps_the_relative_poses_but_the_heading():
    poses = datasets.load_dataset("manhattan:200").ground_truth
    np.testing.assert_allclose(chapter3b.drifted(poses, 0.0), poses, atol=1e-9)
    bent = chapter3b.drifted(poses, 1.3)
    np.testing.assert_allclose(bent[0], poses[0])
    assert se2.wrap_angle(bent[-1, 2] - poses[-1, 2]) == pytest.approx(1.3)
    rel, rel_bent = se2.between(poses[:-1], poses[1:]), se2.between(bent[:-1], bent[1:])
    np.testing.assert_allclose(rel_bent[:, :2], rel[:, :2], atol=1e-9)
    np.testing.assert_allclose(se2.wrap_angle(rel_bent[:, 2] - rel[:, 2]), 1.3 / (len(poses) - 1), atol=1e-12)


def test_drift_basin_finds_the_basin_and_other_stationary_points(graph, capsys):
    fig = chapter3b.drift_basin(graph, "solutions")
    out = capsys.readouterr().out
    assert len(fig.axes) == 2
    assert "the minimum chi2 759.354; Gauss-Newton returns to it from 19 of 33 drifted starts, every drift in " \
           "[-3.53, 3.53] rad (spread over the 199 edges of the chain: up to 0.0178 rad per edge)" in out
    assert "from the others it stops at chi2 5.42e+05 to 5.57e+06" in out


def test_drift_basin_names_the_todo_of_chapter_2(graph, capsys):
    assert chapter3b.drift_basin(graph, "exercises") is None
    out = capsys.readouterr().out
    assert out.startswith("not written yet: TODO ") and "(this figure runs your Gauss-Newton" in out
    assert len(out.splitlines()) == 1


def test_hops_is_the_breadth_first_distance():
    #  0 - 1 - 2 - 3 and a chord 0 - 3; 4 hangs off 2
    d = chapter3b.hops(5, [0, 1, 2, 3, 2], [1, 2, 3, 0, 4], 0)
    assert d.tolist() == [0, 1, 2, 1, 3]


def test_tree_start_satisfies_n_minus_1_edges(graph, capsys):
    fig = chapter3b.tree_start(graph, "solutions")
    out = capsys.readouterr().out
    assert len(fig.axes) == 4  # two panels and their colour bars
    assert "satisfies 199 edges exactly (N - 1 = 199), and the 256 others carry its chi2 1.464e+04" in out
    assert "hops from the anchor: at most 14, mean 7.7; along the file's chain: up to 199" in out


def test_tree_start_names_the_todo(graph, capsys):
    assert chapter3b.tree_start(graph, "exercises") is None
    assert capsys.readouterr().out.startswith("not written yet: TODO initialisation.spanning_tree_poses "
                                              "(your initialisation.py)")


def test_relaxation_is_the_mean_of_the_votes_projected(capsys):
    fig = chapter3b.relaxation()
    out = capsys.readouterr().out.splitlines()
    assert len(fig.axes) == 3
    assert out == ["votes spread over 0.4 rad: relaxed |v| = 0.990, projected angle 0.6059 rad, minimum of the "
                   "wrapped cost 0.6057 rad",
                   "votes spread over 2.8 rad: relaxed |v| = 0.602, projected angle 0.7539 rad, minimum of the "
                   "wrapped cost 0.6399 rad"]
    # the relaxed v of one free orientation with anchored neighbours is the weighted mean of the votes
    w, angles = np.array([1.0, 2.0, 0.5]), 0.6 + np.array([-1.0, 0.3, 1.0]) * 1.4
    mean = (w[:, None] * np.column_stack([np.cos(angles), np.sin(angles)])).sum(0) / w.sum()
    assert np.linalg.norm(mean) == pytest.approx(0.602, abs=5e-4)
    assert np.arctan2(mean[1], mean[0]) == pytest.approx(0.7539, abs=5e-5)


def test_check_relaxed_jacobians(capsys):
    def todo(theta_ij):
        raise NotImplementedError("TODO my_edge_jacobians: write them")

    assert chapter3b.check_relaxed_jacobians(todo) is None
    assert capsys.readouterr().out.startswith("not written yet: TODO my_edge_jacobians: write them (then run")
    right = chapter3b.check_relaxed_jacobians(lambda t: (-se2.rotation(t), np.eye(2)))
    assert right.ok and "Jacobian OK" in capsys.readouterr().out
    wrong = chapter3b.check_relaxed_jacobians(lambda t: (-se2.rotation(t).T, np.eye(2)))
    out = capsys.readouterr().out
    assert not wrong.ok and "d row 0 / d v_i" in out and "v_j" not in out.split("worst entries")[0]


def test_basin_starts(graph, capsys):
    starts = chapter3b.basin_starts(graph, "solutions")
    out = capsys.readouterr().out.splitlines()
    assert set(starts) == {"file", "chordal"} and len(out) == 2
    assert out[1].startswith(f"{graph.name} from chordal (") and "-> 759.354 in" in out[1]
    assert chapter3b.basin_starts(graph, "exercises") is None
    assert capsys.readouterr().out.startswith("not written yet: TODO pose_graph_assembly.")


def test_basin_starts_names_the_initialiser_first(graph, tmp_path, capsys):
    """With chapter 2 written and the initialisers not, the chordal start is the line."""
    import shutil

    from course.core.impl import REPO_ROOT

    shutil.copytree(REPO_ROOT / "solutions", tmp_path / "mine")
    shutil.copy(REPO_ROOT / "exercises" / "initialisation.py", tmp_path / "mine" / "initialisation.py")
    assert chapter3b.basin_starts(graph, str(tmp_path / "mine")) is None
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"{graph.name} from file (") and len(out) == 2
    assert out[1].startswith("not written yet: TODO initialisation.chordal_rotations (your initialisation.py)")


def test_initialiser_table_names_a_todo():
    runs = [RunResult.skipped("ours", "gauss-newton", "not implemented: TODO initialisation.chordal_rotations")]
    runs[0].init = "chordal"
    table = initialiser_table({"toy": runs}, ["gauss-newton"])
    assert "toy           chordal  not implemented: TODO initialisation.chordal_rotations" in table
    assert table.splitlines()[-1] == "lowest final chi2: toy - (no run)"


def test_the_lesson_leaves_the_results_to_the_student():
    """The derivations stop where the exercise starts: no inverse of a relative pose, no Jacobian of
    the relaxed residual, no block of the normal equations, no weight W_k (the hints' levels 2 and 3)."""
    source = build.NOTEBOOKS[build.CHAPTER3B].read_text()
    for result in ("-\\cos", "-cos da", "J_i =", "J_j =", "= -R", "H_{ii}", "H_ii", "W_k =", "W_k = R",
                   "\\Omega_{tt} R", "H_{FF}"):
        assert result not in source, result


# ---------------------------------------------------------------- the executed notebook


@pytest.mark.slow
def test_chapter3b_lesson_executes():
    nb, cells, results, images = _execute(build.CHAPTER3B)
    ids = [c.get("id") for c in nb.cells]
    order = ["figure-drift", "figure-tree", "hint-tree", "check-tree", "figure-relaxation", "check-jacobian",
             "hint-rotations", "check-rotations", "hint-translations", "check-initialisation", "experiments-md",
             "basin", "questions-md"]
    assert [ids.index(name) for name in order] == sorted(ids.index(name) for name in order)
    for cell, name in (("hint-tree", "spanning_tree_poses"), ("hint-rotations", "chordal_rotations"),
                       ("hint-translations", "chordal_translations")):
        assert f"initialisation.{name}, hint 1 of 3" in cells[cell]
    for cell, exercise in (("check-tree", "initialisation.spanning_tree_poses"),
                           ("check-rotations", "initialisation.chordal_rotations"),
                           ("check-initialisation", "initialisation")):
        assert "Autograder: implementation solutions, public checks" in cells[cell]
        assert f"{exercise} (solutions): " in results
    assert "initialisation.chordal_translations" in cells["check-initialisation"]
    assert results.count("full marks on the public checks") == 3, results
    # the Jacobian checker is shown before the check, and a TODO in it is one line
    assert cells["check-jacobian"].startswith("not written yet: TODO my_edge_jacobians")
    assert len(cells["check-jacobian"].splitlines()) == 1
    # the numbers the prose quotes are the ones printed
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    drift = re.search(r"every drift in \[(-?[\d.]+), ([\d.]+)\] rad .* up to ([\d.]+) rad per edge",
                      cells["figure-drift"])
    assert drift and f"$[{drift[1]}, {drift[2]}]$ rad" in markdown["drift-md"] and drift[3] in markdown["drift-md"]
    stops = re.search(r"it stops at chi2 (\S+) to (\S+) ", cells["figure-drift"])
    assert f"between {stops[1]} and {stops[2]}" in markdown["drift-md"]
    for number in ("0.990", "0.602", "0.7539", "0.6399", "0.6059", "0.6057"):
        assert number in cells["figure-relaxation"] and number in markdown["questions-md"]
    # the drift, the tree, the relaxation (theory), the basin (experiments)
    assert len(images) == 4
    _questions(nb, 4)
