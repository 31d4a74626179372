"""Chapter 7's lesson: the helpers of its theory and experiments (``course.notebook_helpers.chapter7``), the
notebook run in the quick setting (a hint and a check per exercise, the checker cells, the figures, the
written questions), its reference answers, and the notebook in a student tree where nothing of chapter 7
is written."""


import nbformat
import numpy as np
import pytest
from conftest import needs
from executed_notebooks import (
    assert_hints_and_checks_at_full_marks,
    assert_no_level_3_hint_line,
    cell_text,
    chapter_1_student_build,
    executed_small,
)

from course.core import peers
from course.core.impl import REPO_ROOT
from course.factorgraph import SE2, FactorGraphProblem, FactorType
from course.geometry.so3 import exp_many, skew
from course.notebook_helpers import chapter7
from notebooks import build
from solutions.jets import Jet

EXERCISES = ("jets", "autodiff_factor", "factor_linearisation")
FIGURES = ["figure-dual", "figure-steps", "figure-series", "figure-pattern", "gps-solve"]


def _gps(z, x):
    return x[..., :2] - z


GPS = FactorType("gps_se2", (SE2,), 2, _gps)


def _drive_graph(drive, keys=None, fixes=None):
    graph = chapter7.odometry_graph(drive)
    keys = drive.gps_keys if keys is None else np.asarray(keys)[:, None]
    graph.add_many(GPS, keys, drive.gps if fixes is None else fixes, np.eye(2) / drive.gps_sigma**2)
    return graph


# ---------------------------------------------------------------- the helpers of the theory


def test_a_todo_is_one_line(capsys):
    with chapter7.todo_as_one_line():
        raise NotImplementedError("TODO jets.sqrt: not implemented yet")
    assert capsys.readouterr().out == "not implemented: TODO jets.sqrt: write it, then run this cell again\n"
    with pytest.raises(ValueError), chapter7.todo_as_one_line():
        raise ValueError("not a TODO: it goes through")


def test_the_dual_number_gives_the_value_and_the_derivative():
    d = chapter7.cubic(chapter7.Dual(2.0, 1.0))
    assert (d.a, d.b) == (3.0, 9.0) and repr(d) == "3 + 9 eps"
    product = chapter7.Dual(1.5, 2.0) * chapter7.Dual(-3.0, 0.5)
    assert (product.a, product.b) == (-4.5, 1.5 * 0.5 + 2.0 * -3.0)  # the product rule, eps^2 dropped
    assert (3 - chapter7.Dual(1.0, 1.0)).b == -1.0 and (2 * chapter7.Dual(1.0, 1.0) + 1).a == 3.0
    for a in (-1.6, 0.4, 1.7):
        assert chapter7.cubic(chapter7.Dual(a, 1.0)).b == pytest.approx(3 * a * a - 3, rel=1e-15)


def test_the_jets_checker_passes_the_reference_and_names_a_wrong_rule():
    lines = []
    result = chapter7.jets_check(Jet, out=lines.append)
    assert result.ok and lines[0] == "values: the 12 rows equal numpy's on floats"
    assert "Jacobian OK: 12 x 2" in lines[1]
    assert len(chapter7.RULES) == 12 and chapter7.small_function(0.7, 1.3).shape == (12,)

    from solutions import jets

    def wrong_sin(x):  # d sin = +sin dx: the derivative of cos taken for sin's, and its sign lost
        return Jet(np.sin(x.value), np.sin(x.value)[..., None] * x.grad)

    original = jets._UFUNCS[np.sin]
    jets._UFUNCS[np.sin] = wrong_sin
    try:
        lines = []
        wrong = chapter7.jets_check(Jet, out=lines.append)
    finally:
        jets._UFUNCS[np.sin] = original
    assert lines[0].startswith("values: the 12 rows")  # the values are right; the derivatives are not
    assert not wrong.ok and "d sin(x) / d x (entry 0)" in wrong.blocks, wrong.blocks
    assert all(("sin" in block or "R(x)" in block) and "/ d x" in block for block in wrong.blocks), wrong.blocks


def test_finite_differences_against_the_jets_by_the_step():
    study = chapter7.step_study("solutions")
    assert study.reference == "the Jets" and study.note == "" and study.jets_vs_complex < 1e-15
    forward, h_forward = study.best("forward")
    central, h_central = study.best("central")
    assert 5e-9 < forward < 1e-7 and 1e-8 < h_forward < 1e-7  # about sqrt(eps)
    assert 5e-12 < central < 1e-10 and 2e-6 < h_central < 5e-5  # about eps^(2/3) at eps^(1/3)
    assert study.forward[-1] > 1e-2 and study.central[-1] < study.forward[-1] / 10  # truncation h, h^2
    table = chapter7.step_table(study)
    assert "forward differences:   smallest error" in table and "the Jets:" in table
    # far from the origin only the rounding grows; the Jets do not move
    far = chapter7.step_study("solutions", shift=1000.0)
    assert far.best("forward")[0] > 3 * forward and far.best("central")[0] > 8 * central
    assert far.jets_vs_complex < 1e-15 and "moved 1000 m" in chapter7.step_table(far)


def test_without_jets_the_reference_is_the_complex_step():
    study = chapter7.step_study("exercises")  # this repository's stubs
    assert study.reference == "the complex step" and study.note.startswith("not implemented: TODO jets.")
    assert study.jets_vs_complex is None
    np.testing.assert_allclose(chapter7.edge_jacobian_by_complex_step(), chapter7.edge_jacobian_by_jets(Jet),
                               rtol=0, atol=1e-15)
    fig = chapter7.step_figure(study)
    assert "TODO jets." in fig.axes[0].get_title()


def test_the_coefficient_b_and_its_derivative():
    t = np.array([1e-6, 1e-3, 0.3, 0.49, 0.51, 1.0, 2.0])
    b, db = chapter7.b_coefficient(t)
    np.testing.assert_allclose(b, 0.5 * np.sinc(t / (2 * np.pi)) ** 2, rtol=1e-14)
    h = 1e-6
    numeric = (chapter7.b_coefficient(t + h)[0] - chapter7.b_coefficient(t - h)[0]) / (2 * h)
    np.testing.assert_allclose(db[2:], numeric[2:], rtol=1e-7)
    np.testing.assert_allclose(db[:2], -t[:2] / 12, rtol=1e-6)
    # what the figure shows: the closed form's derivative has no digit left at the switch, many at 0.1
    for angle, worse in ((chapter7.SWITCH, True), (0.1, False)):
        closed = np.sin(angle) / angle**2 - 2 * (1 - np.cos(angle)) / angle**3
        error = abs(closed - chapter7.b_coefficient([angle])[1][0]) / abs(chapter7.b_coefficient([angle])[1][0])
        assert (error > 0.1) if worse else (error < 1e-8), (angle, error)


def test_exp_on_jets_at_zero():
    table = chapter7.zero_angle_table(Jet)
    assert table.splitlines() == ["closed form alone : 36 of 36 numbers are nan (0/0 at t = 0)",
                                  "with the series   : value - I 0.0e+00, d Exp / d phi_k - [e_k]x 0.0e+00"]


def test_the_chain_rule_through_the_retraction():
    edge = chapter7.se3_edge(seed=0, residual_angle=0.4)
    e = edge.error(edge.T_i, edge.T_j)
    assert np.linalg.norm(e[3:]) == pytest.approx(0.4, abs=1e-12)
    parts = chapter7.chain_rule(edge, Jet)
    assert parts["ambient"].shape == (6, 24) and parts["retraction"].shape == (24, 12)
    assert parts["difference"] < 1e-14
    M = parts["retraction"][:12, :6]
    np.testing.assert_array_equal(M[:3, :3], edge.T_i[1])
    assert not M[:3, 3:].any() and not M[3:, :3].any() and not parts["retraction"][:12, 6:].any()
    # the closed-form plus-Jacobian is the retraction's derivative, and seeding with it gives the same Jacobians
    assert parts["plus_difference"] < 1e-15 and parts["seed_difference"] < 1e-14
    text = chapter7.chain_rule_text(parts, edge)
    assert "largest difference" in text and "is R_i [e_k]x" in text and "SE3.plus_jacobian (closed form)" in text
    from course.factorgraph import SE3
    from course.geometry.jacobian_check import check_jacobian
    from solutions.autodiff_factor import tangent_jacobians

    plus_jacobians = [SE3.plus_jacobian(edge.x_i), SE3.plus_jacobian(edge.x_j)]
    _, (A, B) = tangent_jacobians(edge.residual, plus_jacobians, [edge.x_i, edge.x_j], Jet)
    np.testing.assert_allclose(np.concatenate([A[0], B[0]], axis=1), parts["seeded"], rtol=0, atol=1e-14)
    assert check_jacobian(edge.error, [edge.T_i, edge.T_j], J=[A[0], B[0]], plus="se3", out=None).ok


def test_the_mixed_graph_and_the_pattern_of_its_h():
    from solutions.factor_linearisation import BlockSparseAssembler

    graph = chapter7.mixed_graph()
    assert graph.num_variables == 9 and graph.num_factors == 5 + 12
    assert [k.dim for k in graph.kinds] == [3] * 6 + [2] * 3
    pattern = chapter7.h_pattern(graph)
    assert pattern.shape == (24, 24) and (pattern == pattern.T).all() and pattern.diagonal().all()
    assert not pattern[0:3, 6:9].any()  # x0 and x2 share no factor
    assert pattern[18:20, 0:3].all()  # x0 sees l0
    keys = [g.arrays()[0] for g in graph.groups.values()]
    assembler = BlockSparseAssembler([k.dim for k in graph.kinds], keys, [0])
    assert assembler.nnz == int(np.triu(pattern).sum()) == 162
    assert len(chapter7.pattern_figure(graph).axes) == 1
    _, run = chapter7.solve(graph, "solutions")
    assert run.final_chi2 < 1e-18 and run.initial_chi2 > 1.0
    assert chapter7.run_line(run, "path").startswith("path: chi2 ")


def test_the_figures_draw():
    assert len(chapter7.tangent_figure().axes) == 2
    assert len(chapter7.series_figure().axes) == 2
    assert len(chapter7.step_figure(chapter7.step_study("solutions")).axes) == 1


# ---------------------------------------------------------------- the experiments' helpers


def test_automatic_jacobians_on_intel_are_the_analytic_ones(data_folder):
    (row,) = chapter7.jacobian_agreement(["intel"], "solutions")
    assert row.note == "" and row.factors == 3070
    assert row.autodiff < 1e-12 and 1e-13 < row.numeric < 1e-7
    table = chapter7.agreement_table([row])
    assert table.splitlines()[1].split()[:2] == ["intel", "3070"]
    (todo,) = chapter7.jacobian_agreement(["intel"], "exercises")
    assert todo.note.startswith("not implemented: TODO ")
    runs = chapter7.solve_runs("intel", "solutions")
    assert [r.backend for r in runs] == chapter7.BACKENDS
    assert all(r.final_chi2 == pytest.approx(65.402047738, rel=1e-9) for r in runs)
    line = chapter7.minimum_line(runs)
    assert line.startswith("final chi2 against ours, relative: ours-autodiff lm-type3 ")


def test_a_missing_dataset_is_a_row(monkeypatch, tmp_path):
    monkeypatch.setenv("COURSE_DATA", str(tmp_path / "absent"))
    (row,) = chapter7.jacobian_agreement(["intel"], "solutions")
    assert row.note.startswith("skipped (") and "COURSE_DATA" in row.note
    assert "intel        skipped (" in chapter7.agreement_table([row])


def test_the_gps_drive_is_solved_with_no_jacobian_written_by_hand():
    drive = chapter7.gps_drive(seed=1)
    assert drive.truth.shape == (80, 3) and drive.gps_keys[:, 0].tolist() == list(range(0, 80, 8))
    reckoned = chapter7.dead_reckoning(drive)
    graph = _drive_graph(drive)
    assert not graph.fixed and graph.num_factors == 79 + 10
    problem, run = chapter7.solve(graph, "solutions")
    solved = run.params.reshape(-1, 3)
    assert chapter7.position_error(reckoned, drive.truth) > 3.0
    assert chapter7.position_error(solved, drive.truth) < 0.5
    assert 10 < run.final_chi2 < 30  # about the 17 degrees of freedom
    _, (J,) = problem.factor_jacobians(run.params, list(graph.groups).index("gps_se2"))
    np.testing.assert_array_equal(J, np.broadcast_to(np.eye(2, 3), (10, 2, 3)))
    assert len(chapter7.drive_figure(drive, solved).axes[0].lines) == 4
    assert len(chapter7.drive_figure(drive).axes[0].lines) == 3


def test_one_fix_leaves_the_rotation_free():
    from course.core.errors import SingularSystemError

    drive = chapter7.gps_drive(seed=1)
    with pytest.raises(SingularSystemError, match="not positive definite"):
        chapter7.solve(_drive_graph(drive, [40], drive.gps[5:6]), "solutions")
    _, run = chapter7.solve(_drive_graph(drive, [0, 40], drive.gps[[0, 5]]), "solutions")
    assert np.isfinite(run.final_chi2)


def test_the_range_only_graph_is_built_from_the_library_alone():
    from course.factorgraph import RANGE_2D, between, prior

    ranging = chapter7.range_only()
    graph = chapter7.range_only_graph(ranging)
    assert (graph.num_variables, len(ranging.ranges)) == (84, 143) and not graph.fixed and not graph.fixed_dofs
    assert [g.type for g in graph.groups.values()] == [prior(SE2), between(SE2), RANGE_2D]
    assert graph.keys[80:] == ["b0", "b1", "b2", "b3"]
    # the ranges are the true distances plus noise of their sigma
    pose, beacon = ranging.range_keys.T
    truth = np.linalg.norm(ranging.drive.truth[pose, :2] - ranging.beacons[beacon], axis=1)
    assert 0.05 < np.std(ranging.ranges - truth) < 0.15 and truth.max() <= 14.0
    # the range's Jacobian: minus the unit vector to the beacon, 0 for the heading; plus it for the beacon
    problem = FactorGraphProblem(graph)
    _, (J_pose, J_beacon) = problem.factor_jacobians(problem.x0, list(graph.groups).index(RANGE_2D.name))
    x = problem.x0
    k, j = ranging.range_keys[0]
    d = x[240 + 2 * j:242 + 2 * j] - x[3 * k:3 * k + 2]
    np.testing.assert_allclose(J_pose[0], [[*(-d / np.linalg.norm(d)), 0.0]], rtol=0, atol=1e-15)
    np.testing.assert_allclose(J_beacon[0], [d / np.linalg.norm(d)], rtol=0, atol=1e-15)


def test_range_only_slam_ours_ends_at_gtsams_minimum_or_below():
    ranging = chapter7.range_only()
    runs = chapter7.range_only_runs(ranging, "solutions", repeat=1)
    ours = runs["ours"]
    assert ours.final_chi2 == pytest.approx(137.7748943, rel=1e-8) and ours.initial_chi2 > 1e4
    poses = ours.params[:240].reshape(-1, 3)
    assert chapter7.position_error(poses, ranging.drive.truth) < 0.25 < 1.0 < chapter7.position_error(
        chapter7.dead_reckoning(ranging.drive), ranging.drive.truth)
    table = chapter7.range_only_table(ranging, runs)
    if not peers.installed("gtsam"):
        assert "gtsam is not installed here" in table
        return
    theirs = runs["gtsam"]
    assert theirs.initial_chi2 == ours.initial_chi2  # the same start
    assert ours.final_chi2 <= theirs.final_chi2 * (1 + 1e-12)
    assert ours.final_chi2 == pytest.approx(theirs.final_chi2, rel=1e-8)
    np.testing.assert_allclose(ours.params, theirs.params, rtol=0, atol=1e-4)
    assert "ours - gtsam: -" in table


@needs("gtsam")
def test_gtsams_native_factors_name_what_they_cannot_take():
    from course.backends.factorgraph import gtsam_native
    from course.factorgraph import RANGE_BEARING, FactorGraph, Vector

    graph = FactorGraph("g")
    graph.add_variable("x0", SE2, [0.0, 0.0, 0.0])
    graph.add_variable("l0", Vector(2), [1.0, 1.0])
    graph.add(RANGE_BEARING, ["x0", "l0"], [1.4, 0.8])
    with pytest.raises(ValueError, match="factor type 'range_bearing' has no GTSAM factor here"):
        gtsam_native.build(graph)
    graph.fix("x0")
    with pytest.raises(ValueError, match=r"variable\(s\) \['x0'\] are fixed"):
        gtsam_native.build(graph)
    with pytest.raises(ValueError, match="unknown gtsam method"):
        gtsam_native.solve(graph, "dogleg")


def test_each_pose_kinds_seed_is_its_retractions_derivative_at_zero():
    study = chapter7.plus_jacobian_study()
    P2, diff2 = study["SE2"]
    np.testing.assert_array_equal(P2, np.eye(3))
    P3, diff3 = study["SE3"]
    R = exp_many(np.array([[0.3, -0.2, 0.5]]))[0]
    assert P3.shape == (12, 6) and diff2 < 1e-9 and diff3 < 1e-9
    np.testing.assert_allclose(P3[:3, :3], R, rtol=0, atol=1e-15)  # d t / d rho = R
    for k in range(3):  # d R / d phi_k = R [e_k]x, row by row
        np.testing.assert_allclose(P3[3:, 3 + k].reshape(3, 3), R @ skew(np.eye(3)[k]), rtol=0, atol=1e-15)
    assert not P3[:3, 3:].any() and not P3[3:, :3].any()
    text = chapter7.plus_jacobian_text(study)
    assert "SE3.plus_jacobian(x): d vec(x (+) delta) / d delta at delta = 0, 12 x 6" in text


# ---------------------------------------------------------------- the notebook, quick setting


_outputs = cell_text


def _images(nb):
    return [c.id for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]


@pytest.fixture(scope="module")
def executed():
    from course.core.data import data_dir

    if not data_dir().is_dir():
        pytest.skip(f"data folder {data_dir()} not found (set COURSE_DATA to use another)")
    return executed_small(build.CHAPTER7)


@pytest.mark.slow
def test_the_lesson_runs_with_a_hint_a_check_and_a_checker_per_exercise(executed):
    nb = executed
    text = _outputs(nb)
    assert_hints_and_checks_at_full_marks(nb, (("hint-jets", "check-jets", "jets"),
                                               ("hint-tangent", "check-autodiff", "autodiff_factor"),
                                               ("hint-assembler", "check-linearisation", "factor_linearisation")))
    order = [c.id for c in nb.cells]
    assert order.index("dual-md") < order.index("jets-check") < order.index("check-jets") < order.index(
        "exact-md") < order.index("retraction-md") < order.index("tangent-check") < order.index(
        "check-autodiff") < order.index("linearisation-md") < order.index("check-linearisation")
    assert "values: the 12 rows equal numpy's" in text["jets-check"] and "Jacobian OK: 12 x 2" in text["jets-check"]
    assert "Jacobian OK: 6 x 12" in text["tangent-check"]
    assert "nan (0/0 at t = 0)" in text["zero-angle"] and "[e_k]x 0.0e+00" in text["zero-angle"]
    assert "through the retraction: largest difference" in text["chain-rule"]
    assert "9 variables, 17 factors: chi2 " in text["path-solve"]
    # the lesson does not print the results the hints hold at level 3: no line of them in its cells or outputs
    assert_no_level_3_hint_line("\n".join(c.source for c in nb.cells) + "\n".join(text.values()), EXERCISES)


@pytest.mark.slow
def test_the_lessons_figures_tables_and_numbers(executed):
    nb = executed
    text = _outputs(nb)
    assert _images(nb) == FIGURES
    assert "f(2 + eps) = 3 + 9 eps" in text["figure-dual"]
    assert "differences against the Jets" in text["figure-steps"]
    assert "intel            3070" in text["agreement"]
    assert "65.40204774" in text["minimum"] and "ours-autodiff lm-type3" in text["minimum"]
    assert "sphere2500" not in text["minimum"] and "ladybug" not in text["cost"]  # the full setting only
    assert "medians of 1 interleaved rounds" in text["cost"] and "intel        ours-autodiff" in text["cost"]
    assert "80 poses, 89 factors" in text["gps-solve"] and "[[1. 0. 0.]\n [0. 1. 0.]]" in text["gps-solve"]
    # the seeds: SE(2)'s identity, SE(3)'s 12 x 6, each against central differences of its retraction
    assert "SE2.plus_jacobian(x): d vec(x (+) delta) / d delta at delta = 0, 3 x 3" in text["plus-jacobian"]
    assert "[[1. 0. 0.]\n [0. 1. 0.]\n [0. 0. 1.]]" in text["plus-jacobian"]
    assert "SE3.plus_jacobian(x): d vec(x (+) delta) / d delta at delta = 0, 12 x 6" in text["plus-jacobian"]
    # range-only SLAM: ours and GTSAM's own factors at one minimum (ours at GTSAM's or below), the numbers
    # the answer quotes
    assert "80 poses, 4 beacons, 143 ranges (sigma 0.1 m); start chi2 14335.9" in text["range-only"]
    assert "ours   chi2 137.77489" in text["range-only"]
    assert "poses 0.213 m rms  beacons 0.171 m rms" in text["range-only"]
    if peers.installed("gtsam"):
        assert "gtsam  chi2 137.77489" in text["range-only"] and "ours - gtsam: -" in text["range-only"]
    # the numbers the answers quote are the run's
    study = chapter7.step_study("solutions")
    assert f"{study.best('forward')[0]:.1e} at h = {study.best('forward')[1]:.1e}" in text["figure-steps"]


def test_the_written_questions_and_their_answer_cells():
    nb = build.read(build.NOTEBOOKS[build.CHAPTER7])
    markdown = {c.id: c for c in nb.cells if c.cell_type == "markdown"}
    assert list(markdown)[-7] == "questions-md"
    for k in range(1, 7):
        assert f"**Question {k}.**" in markdown["questions-md"].source
        cell = markdown[f"answer-{k}"]
        assert cell.metadata["tags"] == [build.ANSWER_TAG] and f"Your answer to question {k}" in cell.source
    assert "**Question 7.**" not in markdown["questions-md"].source
    title = markdown["title"].source
    for words in ("Theory", "Experiments", "Written questions", "hint(", "python -m autograder hint NAME LEVEL",
                  "Conventions", "translation first", "right", "retraction"):
        assert words in title, words
    code = "\n".join(c.source for c in nb.cells if c.id == "gps-factor")
    assert "Jacobian" not in code.split("graph = ")[0].replace("no Jacobian", "")  # the factor: no Jacobian
    assert code.count("\n") <= 8


def test_reference_answers_stay_out_of_the_student_tree():
    from autograder.release import stubs as release

    answers = (REPO_ROOT / "solutions" / "answers" / "chapter7.md").read_text()
    assert answers.startswith("# RELEASE: omit")
    for k in range(1, 7):
        assert f"## Question {k}:" in answers
    assert not [name for name in release.render(REPO_ROOT / "solutions") if name.startswith("answers")]


def test_the_lesson_is_registered():
    from autograder.checks import LESSONS

    assert LESSONS["7"] == "notebooks/chapter7_factor_graphs.ipynb"
    assert build.NOTEBOOKS[build.CHAPTER7] == REPO_ROOT / "notebooks" / "chapter7_factor_graphs.py"


# ---------------------------------------------------------------- a student tree, chapter 7 not written (chapter 1 is)


@pytest.mark.slow
def test_in_a_student_tree_the_lesson_builds_and_names_its_todos(python):
    from course.core.data import data_dir

    built = chapter_1_student_build(python)  # the tree (chapter 1 written) and every notebook, once per run
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-3000:]
    nb = nbformat.read(out / "chapter7_factor_graphs.ipynb", as_version=4)
    text = _outputs(nb)
    assert "implementation: exercises" in text["setup"]
    # every TODO is one short line; no cell stops the lesson
    for c in nb.cells:
        for o in c.get("outputs", []):
            assert o.output_type != "error", (c.id, o.get("traceback"))
    for check_id in ("check-jets", "check-autodiff", "check-linearisation"):
        assert "reach a TODO" in text[check_id], text[check_id]
    for cell_id in ("jets-check", "zero-angle", "chain-rule", "tangent-check", "path-solve", "gps-solve"):
        lines = text[cell_id].strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("not implemented: TODO ") and len(lines[0]) < 200, (
            cell_id, lines)
    for hint_id in ("hint-jets", "hint-tangent", "hint-assembler"):
        assert "hint 1 of 3" in text[hint_id]
    # the theory's figures are drawn (the step study against the complex step), and the drive without a solution
    assert _images(nb) == FIGURES
    assert "against the complex step (your Jets: not implemented: TODO jets." in text["figure-steps"]
    if data_dir().is_dir():
        assert "intel        not implemented: TODO " in text["agreement"]
        assert "ours-autodiff  lm-type3  not implemented: TODO factor_linearisation" in text["minimum"]
    assert "Traceback" not in nbformat.writes(nb)
