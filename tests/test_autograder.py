"""The autograder: full marks for solutions, zero with one line per TODO for the stubs,
and each known student mistake or hostile behaviour costs its own checks only.

Variants are built from ``solutions/`` by one-line substitution (tests/student_variants)
and graded through the real command line, with ``--json`` read back.
"""

import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from conftest import needs

pytestmark = pytest.mark.slow  # real grading runs, a child process per check

ROOT = Path(__file__).resolve().parent.parent

from student_variants import (  # noqa: E402
    BUGS,
    HOSTILE,
    TIMEOUT,
    apply,
    assert_loses_exactly,
    build,
    grade_variants,
    losing,
)


def grade_cli(tmp_path, impl, *extra, name="results.json"):
    """Run ``python -m autograder``; return (completed process, parsed results.json)."""
    out = tmp_path / name
    proc = subprocess.run(
        [sys.executable, "-m", "autograder", "--impl", str(impl), "--json", str(out),
         "--timeout", TIMEOUT, *extra],
        cwd=ROOT, capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    return proc, json.loads(out.read_text())


def todos_in_exercises() -> list:
    """``module.qualname`` of every stub in the exercise modules the checks grade."""
    from autograder.checks import modules

    graded = sorted({name for _, module in modules() for name in module.MODULES})
    names = []
    for module in graded:
        text = (ROOT / "exercises" / f"{module}.py").read_text()
        names += re.findall(r'NotImplementedError\("TODO ([\w.]+): not implemented yet"\)', text)
    return names


# ---------------------------------------------------------------- reference and stubs


@needs("pyceres", "qdldl")
def test_solutions_get_full_marks(tmp_path):
    proc, results = grade_cli(tmp_path, "solutions")
    maximum = sum(t["max_score"] for t in results["tests"])
    assert results["score"] == pytest.approx(maximum) and maximum > 0
    assert not losing(results)
    for test in results["tests"]:
        assert set(test) >= {"name", "score", "max_score", "output", "visibility"}
    assert f"Total: {maximum:g} / {maximum:g}" in proc.stdout
    elapsed = float(re.search(r"Elapsed: ([\d.]+) s", proc.stdout).group(1))
    # every check of every chapter, public and hidden: about 30 s on a quiet 2-core machine, so a
    # submission is graded well inside the grader's budget (--budget, 600 s) even on a loaded one
    assert elapsed < 90 and results["execution_time"] == pytest.approx(elapsed, abs=0.1)


@needs("pyceres", "qdldl")
def test_exercises_score_zero_with_one_line_per_todo(tmp_path):
    proc, results = grade_cli(tmp_path, "exercises")
    assert results["score"] == 0
    assert all(t["score"] == 0 for t in results["tests"])
    todos = todos_in_exercises()
    assert len(todos) >= 16
    summary = proc.stdout.split(f"Not implemented ({len(todos)}):\n", 1)[1].splitlines()
    listed = [line.strip() for line in summary if line.startswith("  TODO ")]
    assert sorted(listed) == sorted(f"TODO {name}: not implemented" for name in todos)
    for name in todos:
        assert f"TODO {name}: not implemented" in results["output"]
    for test in results["tests"]:  # every check says which TODO stopped it, in one line
        assert re.fullmatch(r"TODO [\w.]+: not implemented", test["output"]), test


# ---------------------------------------------------------------- student mistakes


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """The known mistakes on every check whose child loads the edited module (the checks left out
    never import it), the hostile variants on every chapter-1 check and one of another chapter:
    one batch run per set of checks."""
    jobs = {name: BUGS[name].loaded_by for name in BUGS} | {name: HOSTILE_CHECKS for name in HOSTILE}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS[name]
    stdout, results = graded[name]
    assert len(results["tests"]) >= 12
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback
    for test in results["tests"]:
        if test["name"] in variant.fails:  # entry, expected and actual, or a plain reason
            assert test["output"] and test["output"] != "ok"


def test_at_least_eight_distinct_mistakes():
    assert len(BUGS) >= 8
    assert len({frozenset(v.fails) | {v.says} for v in BUGS.values()}) == len(BUGS)


# ---------------------------------------------------------------- hostile code

# where a hostile variant is graded: its own checks among the other chapter-1 checks, and one check of
# another chapter (every check runs in a child of its own, so the rest of the suite would tell nothing new)
HOSTILE_CHECKS = ("curve_model", "gauss_newton", "damping", "dogleg", "end_to_end", "pose_graph_3d.retract")


@needs("pyceres", "qdldl")
@pytest.mark.parametrize("name", sorted(HOSTILE))
def test_hostile_code_scores_zero_on_its_checks_and_nothing_else(graded, name):
    variant = HOSTILE[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    by_name = {t["name"]: t for t in results["tests"]}
    for check in variant.fails:
        assert by_name[check]["score"] == 0, by_name[check]
    assert any(variant.says in by_name[check]["output"] for check in variant.fails)
    assert results["score"] == pytest.approx(sum(t["score"] for t in results["tests"]))


def test_a_fake_results_line_changes_nothing(graded):
    stdout, results = graded["fake_results_line"]
    maximum = sum(t["max_score"] for t in results["tests"])
    assert results["score"] < maximum
    total = re.findall(r"^Total: (\S+) / (\S+)$", stdout, flags=re.M)
    assert total == [(f"{results['score']:g}", f"{maximum:g}")]
    # what the student printed is quoted as such, never taken for a result
    quoted = [line for line in stdout.splitlines() if "Score: 100/100" in line]
    assert quoted and all(line.lstrip().startswith("| Score") for line in quoted)


# ---------------------------------------------------------------- command line and protocol


def test_only_selects_an_exercise_or_a_check(tmp_path):
    _, results = grade_cli(tmp_path, "solutions", "--only", "damping.GavinType2", name="a.json")
    assert {t["name"].split(": ")[0] for t in results["tests"]} == {"damping.GavinType2"}
    check = "gauss_newton.solve_step: damped step"
    _, results = grade_cli(tmp_path, "exercises", "--only", check, "--set", "public", name="b.json")
    assert [t["name"] for t in results["tests"]] == [check]
    assert results["tests"][0]["output"] == "TODO gauss_newton.solve_step: not implemented"


@pytest.mark.parametrize("args", [["--impl", "/no/such/dir"], ["--only", "no-such-check"],
                                  ["--timeout", "0"]])
def test_usage_errors_exit_non_zero(args):
    proc = subprocess.run([sys.executable, "-m", "autograder", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "error" in proc.stderr


def test_student_code_never_runs_in_the_grading_process(tmp_path):
    from autograder.grade import grade

    impl = build("normal_equations_no_weights", tmp_path)
    shared = Path(tempfile.mkdtemp())  # the child may run as another user: a folder it can write
    shared.chmod(0o1777)
    marker = shared / "pids"
    marker.touch()
    marker.chmod(0o666)  # each worker slot may run as its own user: all of them append here
    init = impl / "__init__.py"
    # no import statement (the grader refuses os in an exercise package): the pid from /proc
    pid = "open('/proc/self/stat').read().split()[0]"
    init.write_text(init.read_text() + f"\nopen({str(marker)!r}, 'a').write({pid} + '\\n')\n")
    results = grade(str(impl), only=["gauss_newton.normal_equations"], timeout=10, which="public")
    assert [r.score for r in results] == [1.0, 0.0], [r.output for r in results]
    pids = {int(line) for line in marker.read_text().split()}
    assert pids and os.getpid() not in pids
    loaded = [getattr(m, "__file__", None) or "" for m in list(sys.modules.values())]
    assert not any(path.startswith(str(impl)) for path in loaded)


def test_the_parent_refuses_pickles_and_odd_keys_in_the_childs_output(tmp_path):
    from autograder import sandbox

    path = tmp_path / "out.npz"
    np.savez(path, **{"c0.f.value": np.array([1.0, 2.0]), "c1.f.value": np.array([object()], dtype=object),
                      "c2.kind": np.array("value"), "c2.f.value": np.array([3], dtype=np.int64),
                      "__import__": np.array(1.0)})
    outcomes, problem = sandbox._read(path, 3)
    assert outcomes is None and "unreadable" in problem  # the object array is never unpickled
    np.savez(path, **{"c0.kind": np.array("value"), "c0.f.value": np.array([1.0, 2.0]),
                      "c1.kind": np.array("value"), "c1.f.value": np.array([3], dtype=np.int64),
                      "x": np.array(1.0)})
    outcomes, _ = sandbox._read(path, 3)
    assert outcomes[0].fields["value"].tolist() == [1.0, 2.0]
    assert outcomes[1].fields == {}  # integers are not what the child writes: ignored
    assert outcomes[2].error.kind == "Crash"


def test_every_check_is_named_and_documented():
    from autograder.checks import all_checks, modules

    checks = all_checks()
    assert len({c.name for c in checks}) == len(checks)
    for _, module in modules():
        assert module.MODULES and module.CHECKS and module.__doc__
    for check in checks:
        assert check.name.startswith(check.exercise + ": ") and check.points > 0
    variants = {**BUGS, **HOSTILE}
    for variant in variants.values():
        assert variant.fails <= {c.name for c in checks}


def test_variants_apply_cleanly():
    from student_variants import SOLUTIONS, VARIANTS

    for name, variant in VARIANTS.items():
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
