"""The release step: exercises/ is generated from solutions/ and must stay current."""

import shutil

import pytest

from autograder.release import stubs as rel
from course.app.cli import main
from course.core.impl import REPO_ROOT


@pytest.fixture
def repo(tmp_path):
    """A copy of the repository's solutions/ and exercises/ in ``tmp_path / "repo"``."""
    ignore = shutil.ignore_patterns("__pycache__")
    for name in ("solutions", "exercises"):
        shutil.copytree(REPO_ROOT / name, tmp_path / "repo" / name, ignore=ignore)
    return tmp_path / "repo"


def test_committed_exercises_are_up_to_date():
    stale = rel.release(check=True)
    assert stale == [], f"exercises/ is stale, run `python -m course release`: {stale}"


def test_check_fails_on_a_stale_exercise_and_release_fixes_it(repo):
    assert rel.release(check=True, root=repo) == []
    path = repo / "solutions" / "curve_model.py"
    path.write_text(path.read_text().replace("Residuals and Jacobian", "Residuals and the Jacobian", 1))
    assert rel.release(check=True, root=repo) == ["curve_model.py"]
    assert "Residuals and Jacobian" in (repo / "exercises" / "curve_model.py").read_text()  # check writes nothing
    assert rel.release(root=repo) == ["curve_model.py"]
    assert rel.release(check=True, root=repo) == []


def test_extra_and_missing_files_are_stale(repo):
    (repo / "exercises" / "leftover.py").write_text("x = 1\n")
    (repo / "exercises" / "damping.py").unlink()
    assert rel.release(check=True, root=repo) == ["damping.py", "leftover.py"]


def test_cli_release_check_exit_codes(repo, capsys):
    assert main(["release", "--check", "--root", str(repo)]) == 0
    assert "up to date" in capsys.readouterr().out
    path = repo / "solutions" / "gauss_newton.py"
    path.write_text(path.read_text() + "\n# a new line\n")
    assert main(["release", "--check", "--root", str(repo)]) == 1
    out = capsys.readouterr().out
    assert "exercises/gauss_newton.py" in out and "python -m course release" in out
    assert main(["release", "--root", str(repo)]) == 0
    assert main(["release", "--check", "--root", str(repo)]) == 0


def test_solution_blocks_become_todos():
    source = (
        "def f(x):\n"
        '    """Doc."""\n'
        "    # BEGIN SOLUTION\n"
        "    return 2 * x\n"
        "    # END SOLUTION\n"
        "\n\nclass C:\n"
        "    def g(self):\n"
        "        # BEGIN SOLUTION\n"
        "        return 1\n"
        "        # END SOLUTION\n"
    )
    out = rel.strip_solutions(source, "mod")
    assert 'raise NotImplementedError("TODO mod.f: not implemented yet")' in out
    assert 'raise NotImplementedError("TODO mod.C.g: not implemented yet")' in out
    assert "2 * x" not in out and "return 1" not in out and '"""Doc."""' in out
    compile(out, "mod.py", "exec")


@pytest.mark.parametrize("source, message", [
    ("def f():\n    # BEGIN SOLUTION\n    return 1\n", "never closed"),
    ("def f():\n    return 1\n    # END SOLUTION\n", "without"),
    ("# BEGIN SOLUTION\nx = 1\n# END SOLUTION\n", "outside a function"),
    ("def f():\n    # BEGIN SOLUTION\n    # BEGIN SOLUTION\n    return 1\n    # END SOLUTION\n", "inside another"),
])
def test_bad_markers_are_reported(source, message):
    with pytest.raises(rel.ReleaseError, match=message):
        rel.strip_solutions(source, "mod")


def test_omitted_files_and_student_tree(repo, tmp_path):
    (repo / "solutions" / "answers.py").write_text("# RELEASE: omit\nANSWER = 42\n")
    (repo / "tests").mkdir()
    (repo / "tests" / "test_reference.py").write_text("import solutions\n")
    student = tmp_path / "student"
    rel.release(root=repo, student_dir=student)
    assert not (repo / "exercises" / "answers.py").exists()
    assert not (student / "solutions").exists()
    assert not (student / "tests").exists()
    assert (student / "exercises" / "curve_model.py").read_text() == (repo / "exercises" / "curve_model.py").read_text()
    with pytest.raises(rel.ReleaseError, match="already exists"):
        rel.release(root=repo, student_dir=student)
