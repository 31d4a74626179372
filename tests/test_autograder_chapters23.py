"""The autograder on chapters 2 (pose graphs) and 3 (dogleg): full marks for solutions,
zero with one line per TODO for the stubs, and each known mistake costs its own checks
only (graded with ``--only`` on the checks whose child loads the edited module).

Variants are built from ``solutions/`` by one substitution (tests/student_variants,
table ``BUGS_CHAPTERS_2_3``) and graded through the real command line.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import needs

pytestmark = pytest.mark.slow  # real grading runs, a child process per check

ROOT = Path(__file__).resolve().parent.parent

from student_variants import (  # noqa: E402
    BUGS_CHAPTERS_2_3,
    SOLUTIONS,
    TIMEOUT,
    V,
    apply,
    assert_loses_exactly,
    build,
    grade_variants,
)

#: --only names covering every check of chapters 2 and 3
CHAPTERS_2_3 = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast",
                "pose_graph.end_to_end", "dogleg")


def grade_cli(tmp_path, impl, *only, name="results.json"):
    """``python -m autograder --impl IMPL --json ... --only ...``: (process, parsed results.json)."""
    out = tmp_path / name
    args = [a for item in only for a in ("--only", item)]
    proc = subprocess.run(
        [sys.executable, "-m", "autograder", "--impl", str(impl), "--json", str(out), "--timeout", TIMEOUT, *args],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return proc, json.loads(out.read_text())


def losing(results) -> set:
    return {t["name"] for t in results["tests"] if t["score"] < t["max_score"] - 1e-9}


#: the check modules of chapters 2 and 3, in report order
CHECK_MODULES = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast",
                 "pose_graph", "dogleg")


def check_modules() -> list:
    import importlib

    return [importlib.import_module(f"autograder.checks.{name}") for name in CHECK_MODULES]


def chapter_checks() -> list:
    return [check for module in check_modules() for check in module.CHECKS]


def public(results) -> list:
    from autograder.grade import HIDDEN_SUFFIX

    return [t for t in results["tests"] if not t["name"].endswith(HIDDEN_SUFFIX)]


# ---------------------------------------------------------------- reference and stubs


@needs("pyceres", "qdldl")
def test_solutions_get_full_marks_on_chapters_2_and_3(tmp_path):
    proc, results = grade_cli(tmp_path, "solutions", *CHAPTERS_2_3)
    assert [t["name"] for t in public(results)] == [c.name for c in chapter_checks()]
    maximum = sum(t["max_score"] for t in results["tests"])
    assert not losing(results), proc.stdout
    assert results["score"] == pytest.approx(maximum) and f"Total: {maximum:g} / {maximum:g}" in proc.stdout
    # the optional exercise weighs little
    optional = sum(t["max_score"] for t in results["tests"] if t["name"].startswith("pose_graph_fast"))
    assert 0 < optional <= 0.05 * maximum


@needs("pyceres", "qdldl")
def test_exercises_score_zero_with_one_line_per_todo(tmp_path):
    proc, results = grade_cli(tmp_path, "exercises", *CHAPTERS_2_3)
    assert results["score"] == 0 and all(t["score"] == 0 for t in results["tests"])
    todos = []
    for module in dict.fromkeys(name for checks in check_modules() for name in checks.MODULES):
        text = (ROOT / "exercises" / f"{module}.py").read_text()
        todos += re.findall(r'NotImplementedError\("TODO ([\w.]+): not implemented yet"\)', text)
    assert len(todos) == 13  # edge, assembly, 3 solves, 2 Ceres, 3 vectorized, 3 dogleg
    todos.append("curve_model.residuals_and_jacobian")  # the dogleg's curve run uses the student's model
    summary = proc.stdout.split(f"Not implemented ({len(todos)}):\n", 1)[1].splitlines()
    listed = [line.strip() for line in summary if line.startswith("  TODO ")]
    assert sorted(listed) == sorted(f"TODO {name}: not implemented" for name in todos)
    for test in results["tests"]:
        assert re.fullmatch(r"TODO [\w.]+: not implemented", test["output"]), test


def test_an_unwritten_optional_exercise_says_the_loop_is_used(tmp_path):
    """pose_graph_fast left as stubs, the rest written: its checks say the solver falls back."""
    impl = build("dense_solve_no_minus", tmp_path)  # any copy of solutions; sparse_solve is not graded here
    path = impl / "pose_graph_fast.py"
    text = path.read_text()
    for anchors, old, todo in (
            (["def edge_errors_and_jacobians", "# BEGIN SOLUTION"], "xi, xj = poses[edges_i], poses[edges_j]",
             "pose_graph_fast.edge_errors_and_jacobians"),
            (["def __init__", "# BEGIN SOLUTION"],
             "edges_i, edges_j = np.asarray(edges_i, dtype=np.int64), np.asarray(edges_j, dtype=np.int64)",
             "pose_graph_fast.SparseAssembler.__init__")):
        text = apply(text, V("pose_graph_fast.py", anchors, old,
                             f'raise NotImplementedError("TODO {todo}: not implemented yet")', set()))
    path.write_text(text)
    proc, results = grade_cli(tmp_path, impl, "pose_graph_fast", "pose_graph_assembly")
    assert_loses_exactly(results, {c.name for c in chapter_checks() if c.exercise.startswith("pose_graph_fast")},
                         proc.stdout)
    for test in results["tests"]:
        if test["name"].startswith("pose_graph_fast"):
            assert test["output"].startswith("TODO pose_graph_fast.")
            assert "falls back to your per-edge loop" in test["output"]
    assert "Not implemented (2):" in proc.stdout  # the written assemble is not listed


# ---------------------------------------------------------------- student mistakes


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every known mistake of chapters 2 and 3, graded in one batch run per set of checks."""
    jobs = {name: BUGS_CHAPTERS_2_3[name].loaded_by for name in BUGS_CHAPTERS_2_3}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@needs("pyceres", "qdldl")
@pytest.mark.parametrize("name", sorted(BUGS_CHAPTERS_2_3))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_CHAPTERS_2_3[name]
    stdout, results = graded[name]
    assert len(results["tests"]) >= 3
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback
    for test in results["tests"]:
        if test["name"] in variant.fails:
            assert test["output"] and test["output"] != "ok" and not test["output"].startswith("TODO")


def test_the_mistakes_are_distinct_and_name_real_checks():
    names = {c.name for c in chapter_checks()}
    assert len(BUGS_CHAPTERS_2_3) >= 15
    for name, variant in BUGS_CHAPTERS_2_3.items():
        assert variant.fails and variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
    assert len({frozenset(v.fails) | {v.says} for v in BUGS_CHAPTERS_2_3.values()}) == len(BUGS_CHAPTERS_2_3)


# ---------------------------------------------------------------- framework behaviour


def test_the_reference_dogleg_never_refactorizes_between_a_rejection_and_the_retry(data_folder):
    """intel-g2o from its start rejects dogleg steps; each retry reuses the factorization."""
    from autograder.tasks.pose_graph import minimize_pose_graph
    from course.problems.posegraph.dataset import load_dataset
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver import minimize

    graph = load_dataset("intel-g2o")
    result = minimize(PoseGraphProblem(graph), "dogleg")
    trace = result.trace
    rejected = [k for k in range(1, len(trace)) if not trace[k].accepted]
    assert rejected
    for k in rejected:
        if k + 1 < len(trace):
            assert trace[k + 1].factorizations == trace[k].factorizations
    # the end-to-end check reads the same thing from the summary the child returns
    arrays = {"poses": graph.poses, "edges_i": graph.edges_i, "edges_j": graph.edges_j,
              "measurements": graph.measurements, "information": graph.information, "fixed": graph.fixed}
    summary = minimize_pose_graph(arrays, "dogleg", impl="solutions", vectorized=None)
    assert summary["rejected"] == len(rejected) and summary["refactorized_after_rejection"] == 0
    assert summary["final_chi2"] == pytest.approx(result.final_chi2, rel=1e-12)


def test_the_dogleg_case_and_stop_reason_come_back_as_numbers():
    from autograder.tasks.common import decode_text, encode_text
    from autograder.tasks.dogleg import dogleg_step

    assert decode_text(encode_text("steepest-descent")) == "steepest-descent"
    out = dogleg_step(np.array([1.0, 0.0]), np.array([-1e8, 1e4]), 1.0, 1.0 + 2.0**-40, impl=_solutions())
    assert out["case_code"] == 2.0 and decode_text(out["case_text"]) == "dogleg"
    assert not any(isinstance(v, str) for v in out.values())


def _solutions():
    from course.core import impl as impl_loader

    return impl_loader.load("solutions")
