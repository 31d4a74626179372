"""Chapter 2's lesson: the helpers of its theory (``course.notebook_helpers.chapter2``), the notebook run
in the quick setting (a hint and a check cell per exercise, a Jacobian-checker cell where a Jacobian is
derived, the figures, the numbers the prose quotes), its written questions, and the notebook in a student
tree where only chapter 1 is written."""


import nbformat
import numpy as np
import pytest
import scipy.sparse as sp
from executed_notebooks import assert_no_level_3_hint_line, cell_text, chapter_1_student_build, executed_small

from course.core import peers
from course.core.impl import REPO_ROOT
from course.geometry.se2 import between, compose
from course.notebook_helpers import chapter2
from course.problems.posegraph import dataset as datasets
from notebooks import build

EXERCISES = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast")
#: (hint cell, check cell, exercise), in the order of the lesson
CELLS = (("hint-edge", "check-edge", "pose_graph_edge"), ("hint-assembly", "check-assembly", "pose_graph_assembly"),
         ("hint-sparse", "check-sparse", "sparse_solve"), ("hint-ceres", "check-ceres", "ceres_edge_cost"),
         ("hint-fast", "check-fast", "pose_graph_fast"))
THEORY_FIGURES = ["figure-edge", "figure-blocks", "figure-gauge", "figure-fill-in"]
needs_qdldl = pytest.mark.skipif(not peers.installed("qdldl"), reason="qdldl not installed here")


# ---------------------------------------------------------------- the helpers of the theory


def test_a_todo_is_one_line_and_other_errors_go_through(capsys):
    with chapter2.todo_as_one_line():
        raise NotImplementedError("TODO pose_graph_edge.edge_error_and_jacobians: not implemented yet")
    assert capsys.readouterr().out == ("not implemented: TODO pose_graph_edge.edge_error_and_jacobians: write it, "
                                       "then run this cell again\n")
    with chapter2.todo_as_one_line():
        raise ModuleNotFoundError("No module named 'pyceres'", name="pyceres")
    assert capsys.readouterr().out == "not run here: pyceres is not installed (the peers extra)\n"
    with pytest.raises(ValueError), chapter2.todo_as_one_line():
        raise ValueError("not a TODO: it goes through")


def test_the_example_edge_and_its_error():
    from solutions import pose_graph_edge

    x_i, x_j, z_ij = chapter2.example_edge()
    e = chapter2.edge_error(x_i, x_j, z_ij)
    np.testing.assert_allclose(e, between(compose(x_i, z_ij), x_j), atol=1e-12)  # e = (x_i o z_ij)^-1 o x_j
    np.testing.assert_allclose(e, pose_graph_edge.edge_error_and_jacobians(x_i, x_j, z_ij)[0], atol=1e-12)
    assert np.linalg.norm(e[:2]) > 0.3 and abs(e[2] - 0.25) < 1e-12  # visibly off, no angle near pi
    assert len(chapter2.edge_figure(x_i, x_j, z_ij).axes) == 1


def test_edges_apart_joins_row_k_of_each_pose_array():
    from solutions import pose_graph_edge, pose_graph_fast

    g = datasets.load_dataset("manhattan:30")
    X_i, X_j = g.poses[g.edges_i], g.poses[g.edges_j]
    e, A, B = chapter2.edges_apart(pose_graph_fast.edge_errors_and_jacobians, X_i, X_j, g.measurements)
    assert e.shape == (g.num_edges, 3) and A.shape == B.shape == (g.num_edges, 3, 3)
    for k in (0, 17, g.num_edges - 1):
        e_k, A_k, B_k = pose_graph_edge.edge_error_and_jacobians(X_i[k], X_j[k], g.measurements[k])
        np.testing.assert_allclose(e[k], e_k, atol=1e-12)
        np.testing.assert_allclose(A[k], A_k, atol=1e-12)
        np.testing.assert_allclose(B[k], B_k, atol=1e-12)


def test_the_rigid_motions_are_the_null_space_of_j():
    g = datasets.load_dataset("manhattan:30")
    J = chapter2.graph_jacobian(g)
    assert J.shape == (3 * g.num_edges, 3 * g.num_poses)
    for v in chapter2.rigid_motions(g.poses):
        assert np.linalg.norm(J @ v) / np.linalg.norm(v) < 1e-7
    random = np.random.default_rng(1).normal(size=J.shape[1])
    assert np.linalg.norm(J @ random) / np.linalg.norm(random) > 0.1
    # the turn about the origin moves pose p by (-y_p, x_p, 1)
    turn = chapter2.rigid_motions(g.poses)[2].reshape(-1, 3)
    np.testing.assert_allclose(turn, np.column_stack([-g.poses[:, 1], g.poses[:, 0], np.ones(g.num_poses)]))


def test_h_has_three_zero_eigenvalues_free_and_none_with_pose_0_fixed():
    g = datasets.load_dataset("manhattan:30")
    free, fixed = chapter2.gauge_spectra(g)
    assert len(free) == 3 * g.num_poses and len(fixed) == 3 * g.num_poses - 3
    assert np.all(np.abs(free[:3]) < 1e-9 * free[-1]) and free[3] > 1.0
    assert fixed[0] > 1.0
    np.testing.assert_allclose(fixed[0], 26.0, rtol=0.05)  # "its smallest is 26" (the reference answers)
    table = chapter2.gauge_table(g)
    assert "turn about the origin (-y_p, x_p, 1)" in table
    assert "a random direction (for comparison)           2.2e+00" in table  # "about 2" in the prose
    assert "smallest eigenvalues of H, pose 0 fixed:    2.6e+01" in table
    assert len(chapter2.gauge_figure(g).axes) == 1


def test_the_block_structure_figure():
    g = datasets.load_dataset("manhattan:12")
    assert (int(g.edges_i[12]), int(g.edges_j[12])) == (1, 9)  # the loop closure the prose names
    assert len(chapter2.block_structure_figure(g, edge=12).axes) == 3


def test_the_pattern_is_the_one_the_solver_assembles():
    from solutions import pose_graph_fast

    g = datasets.load_dataset("manhattan:100")
    pattern = chapter2.upper_pattern(g.num_poses, g.edges_i, g.edges_j)
    e, A, B = pose_graph_fast.edge_errors_and_jacobians(g.poses, g.edges_i, g.edges_j, g.measurements)
    H, _, _ = pose_graph_fast.SparseAssembler(g.num_poses, g.edges_i, g.edges_j, g.fixed).assemble(
        e, A, B, g.information)
    assert np.array_equal(pattern.indptr, H.indptr) and np.array_equal(pattern.indices, H.indices)


def _star(leaves, hub_first):
    """The upper-triangle pattern of a star: one hub joined to every leaf (scalar variables)."""
    n = leaves + 1
    hub = 0 if hub_first else n - 1
    others = [k for k in range(n) if k != hub]
    rows = np.array([min(hub, k) for k in others] + list(range(n)))
    cols = np.array([max(hub, k) for k in others] + list(range(n)))
    return sp.csc_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))


def test_the_star_fills_with_the_hub_first_and_not_with_the_hub_last():
    n = 8
    assert chapter2.fill_in(_star(n - 1, hub_first=True))["L"] == n * (n + 1) // 2  # dense
    last = chapter2.fill_in(_star(n - 1, hub_first=False))
    assert last["L"] == last["H"] == 2 * n - 1 and last["fill"] == 0
    # reordering the hub-first star with the hub last removes the fill
    order = np.r_[1:n, 0]
    assert chapter2.fill_in(_star(n - 1, hub_first=True), order)["L"] == 2 * n - 1


def test_the_symbolic_pattern_is_the_numeric_factors():
    g = datasets.load_dataset("manhattan:30")
    upper = chapter2.upper_pattern(g.num_poses, g.edges_i, g.edges_j)
    # a positive definite matrix with exactly this pattern: its dense Cholesky factor has L's pattern
    values = sp.csc_matrix(upper, copy=True)
    values.data[:] = -1.0
    full = (values + sp.triu(values, k=1).T).toarray()
    full[np.diag_indices_from(full)] = np.abs(full).sum(axis=1) + 1.0
    L = np.linalg.cholesky(full)
    pattern = chapter2.cholesky_pattern(upper).toarray() != 0
    assert np.array_equal(pattern, np.abs(L) > 1e-14)
    order = np.random.default_rng(0).permutation(len(full))
    L = np.linalg.cholesky(full[order][:, order])
    assert np.array_equal(chapter2.cholesky_pattern(upper, order).toarray() != 0, np.abs(L) > 1e-14)


@needs_qdldl
def test_fill_in_counts_match_qdldl_and_the_prose():
    import qdldl

    g = datasets.load_dataset("manhattan:100")
    upper = chapter2.upper_pattern(g.num_poses, g.edges_i, g.edges_j)
    order, name = chapter2.amd_order(upper)
    assert name == "AMD (qdldl)" and sorted(order) == list(range(3 * g.num_poses))
    natural, reordered = chapter2.fill_in(upper), chapter2.fill_in(upper, order)
    assert (natural["H"], natural["L"], reordered["L"]) == (2634, 28446, 6936)  # the numbers the prose quotes
    values = sp.csc_matrix(upper, copy=True)
    values.data[:] = 0.5
    values = values + sp.diags(np.full(values.shape[0], 100.0))
    L, _, _ = qdldl.Solver(sp.triu(values, format="csc"), upper=True).factors()
    assert L.nnz + values.shape[0] == reordered["L"]  # qdldl's own factor (unit diagonal left out)
    table = chapter2.fill_in_table([g])
    assert table.splitlines()[-1].split() == ["manhattan:100:0", "100", "226", "2634", "28446", "3.2e+06", "6936",
                                              "1.82e+05", "AMD", "(qdldl)"]
    assert len(chapter2.fill_in_figure(g).axes) == 3


def test_the_growth_figure():
    fig = chapter2.growth_figure([100, 200], [1e-3, 8e-3], [2e-4, 4e-4], (3.0, 1.0))
    assert [line.get_label() for line in fig.axes[0].lines] == [
        "dense (dense_solve), slope 3.00", "sparse (SparseCholeskySolver), slope 1.00"]


# ---------------------------------------------------------------- the lesson's source


def _lesson():
    return build.read(build.NOTEBOOKS[build.CHAPTER2])


def test_the_lesson_is_in_order_theory_experiments_questions():
    nb = _lesson()
    order = [c.id for c in nb.cells]
    for hint_id, check_id, exercise in CELLS:
        cells = {c.id: c for c in nb.cells}
        assert f'check("{exercise}")' in cells[check_id].source
        assert cells[hint_id].source.startswith("hint(") and ", 1)" in cells[hint_id].source
        assert order.index(hint_id) < order.index(check_id) < order.index("experiments-md")
    assert order.index("edge-md") < order.index("update-md") < order.index("chain-md") < order.index(
        "jacobian-check") < order.index("check-edge") < order.index("assembly-md") < order.index(
        "gauge-md") < order.index("check-assembly") < order.index("cholesky-md") < order.index(
        "check-sparse") < order.index("ceres-md") < order.index("ceres-jacobian-check") < order.index(
        "check-ceres") < order.index("fast-md") < order.index("fast-jacobian-check") < order.index("check-fast")
    assert order.index("experiments-md") < order.index("intel-md") < order.index("split") < order.index(
        "questions-md")
    title = {c.id: c.source for c in nb.cells}["title"]
    for words in ("Theory", "Experiments", "Written questions", "hint(", "python -m autograder hint",
                  "Conventions", "plain addition", *EXERCISES):
        assert words in title, words
    for cell_id in ("jacobian-check", "ceres-jacobian-check", "fast-jacobian-check"):
        source = {c.id: c.source for c in nb.cells}[cell_id]
        assert "check_jacobian(" in source and "chapter2.todo_as_one_line()" in source


def test_the_lesson_does_not_print_the_level_3_hints():
    """No line of the five exercises' level-3 hints is in the lesson's cells (the outputs: the slow test)."""
    lesson = " ".join("\n".join(c.source for c in _lesson().cells).split())
    assert assert_no_level_3_hint_line(lesson, EXERCISES) >= 5
    # nor the Jacobians' matrices written out
    for words in ("[[-R_ij^T R_i^T", "A_ij = [[", "H[i,i] += A^T Omega A", "-Q, (-sin phi dx"):
        assert words not in lesson


def test_the_written_questions_and_their_answer_cells():
    nb = _lesson()
    markdown = {c.id: c for c in nb.cells if c.cell_type == "markdown"}
    assert list(markdown)[-6] == "questions-md"
    questions = markdown["questions-md"].source
    for k in range(1, 6):
        assert f"**Question {k}.**" in questions
        cell = markdown[f"answer-{k}"]
        assert cell.metadata["tags"] == [build.ANSWER_TAG] and f"Your answer to question {k}" in cell.source
    assert "**Question 6.**" not in questions
    # the two questions that were there are kept word for word
    for words in ("Which step of an iteration takes the most time, and how can it be made\n# faster?",
                  "Which other methods for nonlinear least squares (and nonlinear\n# optimization in general)"):
        assert words.replace("\n# ", "\n") in questions, words
    # the numbers the questions and the prose quote are the ones the helpers print
    assert "more than four times" in questions and 28446 > 4 * 6936
    cholesky = markdown["cholesky-md"].source
    for number in ("28446", "2634", "6936"):
        assert number in cholesky


def test_reference_answers_of_every_question_stay_out_of_the_student_tree():
    from autograder.release import stubs as release

    answers = (REPO_ROOT / "solutions" / "answers" / "chapter2.md").read_text()
    assert answers.startswith("# RELEASE: omit")
    for k in range(1, 6):
        assert f"## Question {k}:" in answers
    for number in ("2634", "28446", "6936", "1278495", "58446"):  # the table the notebook prints
        assert number in answers
    assert not [name for name in release.render(REPO_ROOT / "solutions") if name.startswith("answers")]


# ---------------------------------------------------------------- the notebook, quick setting


_outputs = cell_text


@pytest.fixture(scope="module")
def executed():
    return executed_small(build.CHAPTER2)


@pytest.mark.slow
def test_the_lesson_runs_with_a_hint_a_check_and_a_checker_per_exercise(executed):
    text = _outputs(executed)
    errors = [(c.id, o.get("ename"), o.get("evalue")) for c in executed.cells if c.cell_type == "code"
              for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    assert "implementation: solutions; setting: quick" in text["setup"]
    for hint_id, check_id, exercise in CELLS:
        assert "hint 1 of 3" in text[hint_id] and "Hint 2" not in text[hint_id], hint_id
        assert "Autograder: implementation solutions, public checks" in text[check_id]
        assert f"{exercise} (solutions): " in text[check_id]
        assert "full marks on the public checks" in text[check_id], text[check_id]
    assert "Jacobian OK: 3 x 6" in text["jacobian-check"]
    assert "Jacobian WRONG: 1 of 18 entries" in text["jacobian-check"]
    assert "d translation / d x_i rotation" in text["jacobian-check"]
    assert "Jacobian OK: 3 x 6" in text["ceres-jacobian-check"] or "pyceres is not installed" in text[
        "ceres-jacobian-check"]
    assert "Jacobian OK: 186 x 372" in text["fast-jacobian-check"]
    # nor do the outputs hold a line of the level-3 hints
    assert_no_level_3_hint_line("\n".join(text.values()), EXERCISES)


@pytest.mark.slow
def test_the_lessons_figures_and_numbers(executed):
    text = _outputs(executed)
    images = [c.id for c in executed.cells if c.cell_type == "code" for o in c.outputs
              if "image/png" in o.get("data", {})]
    assert images == [*THEORY_FIGURES, "intel", "growth"]
    assert "a random direction (for comparison)           2.2e+00" in text["figure-gauge"]
    assert "manhattan:100:0    100   226     2634        28446" in text["figure-fill-in"]
    if peers.installed("qdldl"):
        assert "6936   1.82e+05  AMD (qdldl)" in text["figure-fill-in"]


# ---------------------------------------------------------------- a student tree with chapter 1 written


@pytest.mark.slow
def test_in_a_student_tree_with_chapter_1_written_the_lesson_builds_and_names_its_todos(python, tmp_path):
    built = chapter_1_student_build(python)  # the tree and every notebook built once per test run
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-3000:]
    nb = nbformat.read(out / "chapter2_pose_graphs.ipynb", as_version=4)
    text = _outputs(nb)
    assert "implementation: exercises" in text["setup"]
    # every error is one short line naming what is not written (or what a cell above did not compute)
    for c in nb.cells:
        for o in c.get("outputs", []):
            if o.output_type == "error":
                assert len(o["traceback"]) == 1 and len(o["traceback"][0]) < 400, (c.id, o["traceback"])
                assert "TODO" in o["traceback"][0], (c.id, o["traceback"])
    for hint_id, check_id, _ in CELLS:
        assert "hint 1 of 3" in text[hint_id]
        assert "reach a TODO" in text[check_id], text[check_id]
    for cell_id in ("jacobian-check", "ceres-jacobian-check", "fast-jacobian-check"):
        assert "not implemented: TODO" in text[cell_id] and "run this cell again" in text[cell_id], text[cell_id]
        assert all(o.output_type == "stream" for o in {c.id: c for c in nb.cells}[cell_id].outputs)
    # the theory's figures need no exercise
    images = [c.id for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]
    assert images[:4] == THEORY_FIGURES
    assert "Traceback" not in nbformat.writes(nb)
