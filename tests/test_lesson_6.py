"""Chapter 6's lesson: the helpers of its theory (``course.notebook_helpers.chapter6``), the notebook run
in the quick setting (a hint, a check and, where a Jacobian is derived, a checker cell per exercise; the
figures; the written questions), and the notebook in a student tree where only chapter 1 is written."""


import re

import nbformat
import numpy as np
import pytest
from executed_notebooks import (
    assert_hints_and_checks_at_full_marks,
    assert_no_level_3_hint_line,
    cell_text,
    chapter_1_student_build,
    executed_small,
)

from course.core.impl import REPO_ROOT
from course.geometry.jacobian_check import check_jacobian, numerical_jacobian
from course.geometry.so3 import exp_many
from course.notebook_helpers import chapter6
from course.problems.posegraph3d.graph import PoseGraph3D
from notebooks import build

EXERCISES = ("pose_graph_3d", "pose_graph_3d_assembly", "chordal_3d", "gnc")


def _ring(n=10, closures=((0, 5),)):
    """A consistent 3D graph: n poses on a circle (each turned 36 degrees about z from the last), the
    odometry i -> i+1 and the given loop closures, every measurement exact, unit information."""
    yaw = np.arange(n) * 2 * np.pi / n
    R = exp_many(np.stack([np.zeros(n), np.zeros(n), yaw], axis=1))
    t = np.stack([np.cos(yaw), np.sin(yaw), np.zeros(n)], axis=1) * 3.0
    pairs = [(k, k + 1) for k in range(n - 1)] + list(closures)
    ei, ej = np.array(pairs).T
    R_z = np.matmul(R[ei].transpose(0, 2, 1), R[ej])
    t_z = np.einsum("mba,mb->ma", R[ei], t[ej] - t[ei])
    return PoseGraph3D(t, R, ei, ej, t_z, R_z, np.tile(np.eye(6), (len(ei), 1, 1)), name="ring")


# ---------------------------------------------------------------- the helpers of the theory


def test_a_todo_is_one_line(capsys):
    with chapter6.todo_as_one_line():
        raise NotImplementedError("TODO gnc.tls_weights: not implemented yet")
    assert capsys.readouterr().out == ("not implemented: TODO gnc.tls_weights: write it, then run this cell "
                                       "again\n")
    with pytest.raises(ValueError), chapter6.todo_as_one_line():
        raise ValueError("not a TODO: it goes through")


def test_the_right_jacobian_makes_the_first_order_form_exact_to_first_order():
    angles = np.radians([5.0, 49.0, 120.0])
    naive, with_jr = chapter6.first_order_errors(angles, step=1e-3)
    # at 49 degrees: about 30% of |delta| with I, second order (below 1e-3 |delta|) with J_r^-1
    np.testing.assert_allclose(naive[1], 0.298, atol=0.01)
    assert np.all(with_jr < 1e-3) and np.all(with_jr < naive / 100)
    assert np.all(np.diff(naive) > 0)  # the identity gets worse as the angle grows
    # halving the step halves the relative error of the J_r^-1 form (second order), not that of I
    _, half = chapter6.first_order_errors(angles, step=5e-4)
    np.testing.assert_allclose(half / with_jr, 0.5, rtol=0.05)


def test_the_random_edge_has_the_residual_rotation_asked_for_and_feeds_the_checker(capsys):
    from solutions import pose_graph_3d

    edge = chapter6.random_edge(seed=0, residual_angle=0.5)
    assert abs(edge.residual_angle - 0.5) < 1e-12
    e, A, B = pose_graph_3d.edge_errors_and_jacobians(*edge.arguments())
    np.testing.assert_allclose(np.linalg.norm(e[0, 3:]), 0.5, rtol=1e-12)

    def error(T_i, T_j):
        return pose_graph_3d.edge_errors_and_jacobians(*edge.arguments(T_i, T_j))[0][0]

    ok = check_jacobian(error, [edge.T_i, edge.T_j], J=[A[0], B[0]], plus="se3", names=["T_i", "T_j"],
                        rows="se3", out=None)
    assert ok.ok
    slip = B[0].copy()
    slip[4, 5] += 0.1
    wrong = check_jacobian(error, [edge.T_i, edge.T_j], J=[A[0], slip], plus="se3", names=["T_i", "T_j"],
                           rows="se3", out=None)
    assert not wrong.ok and wrong.wrong == 1 and list(wrong.blocks) == ["d rotation / d T_j rotation"]


def test_fill_in_of_a_ring_in_file_order():
    """A ring of n poses, eliminated in order: each pose connects its next neighbour to the last one."""
    n = 10
    ring = _ring(n, closures=((0, n - 1),))
    natural = chapter6.fill_in(ring.num_poses, ring.edges_i, ring.edges_j, "NATURAL")
    assert natural["H"] == n + n  # the diagonal and one block per edge
    assert natural["L"] == 3 * n - 3  # the diagonal, the sub-diagonal and the last row
    chain = chapter6.fill_in(n, np.arange(n - 1), np.arange(1, n), "NATURAL")
    assert chain["L"] == 2 * n - 1  # no fill-in at all
    assert chapter6.fill_in(ring.num_poses, ring.edges_i, ring.edges_j)["L"] <= natural["L"]
    table = chapter6.fill_in_table([ring])
    assert table.splitlines()[-1].split() == ["ring", "10", "10", "20", "27", str(chapter6.fill_in(
        ring.num_poses, ring.edges_i, ring.edges_j)["L"])]


def test_the_relaxation_of_a_consistent_graph_gives_rotations():
    ring = _ring()
    np.testing.assert_allclose(chapter6.relaxed_singular_values(ring, "solutions"), 1.0, atol=1e-9)
    hops = chapter6.hops_from(ring.num_poses, ring.edges_i, ring.edges_j)
    assert hops[0] == 0 and hops[1] == 1 and hops[5] == 1 and hops.max() == 5  # pose 9: 0 -> 5 -> 6 -> ... -> 9


def test_the_chordal_distance_is_twice_the_squared_angle_for_small_angles():
    theta = np.array([1e-3, 0.3, np.pi])
    R_a = exp_many(np.array([[0.1, 0.2, 0.3]]))[0]
    for angle in theta:
        R_b = R_a @ exp_many(np.array([[0.0, 0.0, angle]]))[0]
        np.testing.assert_allclose(np.sum((R_a - R_b) ** 2), chapter6.chordal_distance(angle), rtol=1e-9)
    np.testing.assert_allclose(chapter6.chordal_distance(1e-3), 2e-6, rtol=1e-6)


@pytest.mark.parametrize("mu", [0.05, 0.3, 1.0, 20.0])
def test_the_reference_tls_weights_are_the_surrogates_derivative(mu):
    from solutions import gnc

    c2 = 16.81
    s = np.linspace(0.1, 5 * c2 * (mu + 1) / mu, 40)
    numeric = np.diag(numerical_jacobian(lambda v: chapter6.tls_surrogate(v, mu, c2), s))
    np.testing.assert_allclose(numeric, gnc.tls_weights(s, mu, c2), atol=1e-5)
    lower, upper = mu / (mu + 1) * c2, (mu + 1) / mu * c2
    np.testing.assert_allclose(chapter6.tls_surrogate([0.0, lower, upper, 10 * upper], mu, c2),
                               [0.0, lower, c2, c2], rtol=1e-12)  # continuous at both bounds
    assert np.all(np.diff(chapter6.tls_surrogate(s, mu, c2)) >= -1e-12)


@pytest.mark.parametrize("mu", [1.0, 3.0, 50.0])
def test_the_reference_gm_weights_are_the_surrogates_derivative(mu):
    from solutions import gnc

    c2 = 16.81
    s = np.linspace(0.0, 10 * c2, 40)
    numeric = np.diag(numerical_jacobian(lambda v: chapter6.gm_surrogate(v, mu, c2), s))
    np.testing.assert_allclose(numeric, gnc.gm_weights(s, mu, c2), atol=1e-6)


def test_the_figures_draw_and_a_todo_is_written_in_its_panel():
    ring = _ring()
    assert len(chapter6.perturbation_figure().axes) == 2
    assert len(chapter6.right_jacobian_figure().axes) == 1
    assert len(chapter6.sparsity_figure(ring).axes) == 3
    assert len(chapter6.surrogate_figure().axes) == 2
    assert len(chapter6.chordal_figure(ring, "solutions").axes) == 2
    todo = chapter6.chordal_figure(ring, "exercises")  # this repository's stubs: a TODO
    texts = [t.get_text() for t in todo.axes[1].texts]
    assert texts and "TODO chordal_3d.relaxed_rotations" in texts[0]


def test_the_gnc_weights_figure_and_table():
    from course.problems.posegraph3d.robust import RobustRun

    outliers = np.array([False, False, True, False])
    odometry = np.array([True, False, False, False])
    weights = [np.ones(4), np.array([1.0, 0.4, 0.1, 0.8]), np.array([1.0, 1.0, 0.0, 0.0])]
    run = RobustRun("GNC TLS", np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)), weights[-1] > 0.5,
                    extra={"mus": [0.01, 0.014], "weights": weights})
    fig = chapter6.gnc_weights_figure([run], outliers, odometry)
    assert len(fig.axes) == 1 and len(fig.axes[0].lines) == 3 + 2  # three closures, two legend entries
    assert chapter6.gnc_rounds_table([run], outliers, odometry) == (
        "ours GNC TLS: 2 rounds after least squares (mu 0.01 to 0.014); kept 0 of 1 wrong closures, "
        "rejected 1 of 2 right ones")


# ---------------------------------------------------------------- the notebook, quick setting


def _outputs(nb):
    return {c.id: c for c in nb.cells}, cell_text(nb)


@pytest.fixture(scope="module")
def executed():
    from course.core.data import data_dir

    if not data_dir().is_dir():
        pytest.skip(f"data folder {data_dir()} not found (set COURSE_DATA to use another)")
    return executed_small(build.CHAPTER6)


@pytest.mark.slow
def test_the_lesson_runs_with_a_hint_a_check_and_a_checker_per_exercise(executed):
    cells, text = _outputs(executed)
    assert_hints_and_checks_at_full_marks(executed, (("hint-edge", "check-edge", "pose_graph_3d"),
                                                     ("hint-assembly", "check-assembly", "pose_graph_3d_assembly"),
                                                     ("hint-chordal", "check-chordal", "chordal_3d"),
                                                     ("hint-gnc", "check-gnc", "gnc")))
    order = [c.id for c in executed.cells]
    # the theory comes first, in the order of the exercises; the checker before the edge's check
    assert order.index("so3-md") < order.index("edge-md") < order.index("jacobian-check") < order.index(
        "check-edge") < order.index("assembly-md") < order.index("chordal-md") < order.index("gnc-md")
    assert order.index("weights-check") < order.index("check-gnc")
    assert "Jacobian OK: 6 x 12" in text["jacobian-check"]
    assert "Jacobian WRONG: 1 of 72 entries" in text["jacobian-check"]
    assert "d rotation / d T_j rotation" in text["jacobian-check"]
    assert text["weights-check"].count("Jacobian OK: 6 x 6") == 2
    # the lesson does not print the results the hints hold at level 3: no line of them in its cells or outputs
    assert_no_level_3_hint_line("\n".join(c.source for c in executed.cells) + "\n".join(text.values()), EXERCISES)
    from autograder.hints import hint_sources

    assert "H_ii += w I" in hint_sources()["chordal_3d"]["relaxed_rotations"][2]  # what the check above reads


@pytest.mark.slow
def test_the_lessons_figures_tables_and_numbers(executed):
    cells, text = _outputs(executed)
    images = [c.id for c in executed.cells if c.cell_type == "code" for o in c.outputs
              if "image/png" in o.get("data", {})]
    assert images == ["figure-perturbations", "figure-right-jacobian", "figure-sparsity", "figure-chordal",
                      "figure-surrogates", "trajectories", "spectrum", "gnc-weights"]
    assert "smallGrid3D                  125   297      422          2723           1356" in text["figure-sparsity"]
    assert "smallGrid3D+20% wrong        125   297      422          3103           1433" in text["figure-sparsity"]
    assert "kept 0 of 35 wrong closures" in text["gnc-weights"]
    assert "threshold c2 = 16.81" in text["outliers"]
    # numbers the prose and the questions quote are the ones printed
    assert "median 13.1168 deg" in text["spectrum"] and "median 18.2457 deg, max 49.331 deg" in text["spectrum"]
    markdown = {c.id: c.source for c in executed.cells if c.cell_type == "markdown"}
    assert "reach 49 degrees" in markdown["experiments-md"] and "16.81" in markdown["gnc-md"]


def test_the_written_questions_and_their_answer_cells():
    nb = build.read(build.NOTEBOOKS[build.CHAPTER6])
    markdown = {c.id: c for c in nb.cells if c.cell_type == "markdown"}
    assert list(markdown)[-6] == "questions-md"
    for k in range(1, 6):
        assert f"**Question {k}.**" in markdown["questions-md"].source
        cell = markdown[f"answer-{k}"]
        assert cell.metadata["tags"] == [build.ANSWER_TAG] and f"Your answer to question {k}" in cell.source
    assert "**Question 6.**" not in markdown["questions-md"].source
    # the existing two questions are kept word for word
    for words in ("rotation information of about 400 where the gtsam", "need the odometry as known inliers"):
        assert words in markdown["questions-md"].source
    title = markdown["title"].source
    for words in ("Theory", "Experiments", "Written questions", "hint(", "python -m autograder hint NAME LEVEL",
                  "Conventions", "translation first", "right"):
        assert words in title, words


def test_reference_answers_of_every_question_stay_out_of_the_student_tree():
    from autograder.release import stubs as release

    answers = (REPO_ROOT / "solutions" / "answers" / "chapter6.md").read_text()
    assert answers.startswith("# RELEASE: omit")
    for k in range(1, 6):
        assert f"## Question {k}:" in answers
    assert not [name for name in release.render(REPO_ROOT / "solutions") if name.startswith("answers")]


# ---------------------------------------------------------------- a student tree with chapter 1 written


@pytest.mark.slow
def test_in_a_student_tree_with_chapter_1_written_the_lesson_builds_and_names_its_todos(python, tmp_path):
    from course.core.data import data_dir
    if not data_dir().is_dir():
        pytest.skip(f"data folder {data_dir()} not found (set COURSE_DATA to use another)")
    built = chapter_1_student_build(python)  # the tree and every notebook built once per test run
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-3000:]
    nb = nbformat.read(out / "chapter6_pose_graphs_3d.ipynb", as_version=4)
    cells, text = _outputs(nb)
    assert "implementation: exercises" in text["setup"]
    # every traceback is one short line naming what is not written; no cell stops the lesson
    for c in nb.cells:
        for o in c.get("outputs", []):
            if o.output_type == "error":
                assert len(o["traceback"]) == 1 and len(o["traceback"][0]) < 300, (c.id, o["traceback"])
                assert "TODO" in o["traceback"][0], (c.id, o["traceback"])
    for check_id in ("check-edge", "check-assembly", "check-chordal", "check-gnc"):
        assert "reach a TODO" in text[check_id], text[check_id]
    for cell_id in ("jacobian-check", "weights-check"):
        assert "not implemented: TODO" in text[cell_id] and "run this cell again" in text[cell_id]
        assert not cells[cell_id].outputs or all(o.output_type == "stream" for o in cells[cell_id].outputs)
    for hint_id in ("hint-edge", "hint-assembly", "hint-chordal", "hint-gnc"):
        assert "hint 1 of 3" in text[hint_id]
    # the theory's figures that need no exercise are drawn; the rest name their TODO
    images = [c.id for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]
    assert {"figure-perturbations", "figure-right-jacobian", "figure-sparsity", "figure-chordal",
            "figure-surrogates"} <= set(images)
    assert "not implemented: TODO" in text["compare"] and re.search(r"^g2o +gauss-newton ", text["compare"], re.M), \
        text["compare"]
    assert "Traceback" not in nbformat.writes(nb)
