"""The student tree (``python -m course release --student DIR``): what it holds, and that it
runs on its own, without the instructor's repository.

The tree's commands run in subprocesses with ``cwd`` = the tree and
``PYTHONPATH`` = the tree, on an interpreter that sees this venv's installed packages
(numpy, pyceres, ...) but not its editable install of this repository: the editable
finder would map ``course``/``solutions``/``exercises``/``autograder`` back to the
instructor's checkout (``import solutions`` would succeed). So a throw-away venv (no pip)
gets a ``.pth`` file naming this venv's site-packages folder; ``.pth`` files inside that
folder (the editable finder's) are not run, so only the tree is importable, and every
child process the tree starts (the autograder's) gets the same view.
"""

import json
import os
import re
import shutil
import subprocess
import sys
import venv
from pathlib import Path

import nbformat
import pytest
from executed_notebooks import chapter_1_student_build

from autograder.release import stubs as rel
from course.app.cli import main
from course.core.data import data_dir
from course.core.impl import REPO_ROOT, not_implemented_reason
from course.core.trace import RunResult
from notebooks.build import NOTEBOOKS

TEMPLATES = REPO_ROOT / "autograder" / "release" / "student_tree"


def _write_tree(target: Path) -> Path:
    """A student tree of this repository at ``target`` (``check=True``: the repository's own
    ``exercises/`` stays untouched; the tree gets the freshly rendered one)."""
    rel.release(check=True, student_dir=target)
    return target


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    return _write_tree(tmp_path_factory.mktemp("student") / "tree")


def _run(python, tree, *args, timeout=300):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL"))}
    env["PYTHONPATH"] = str(tree)
    return subprocess.run([python, *args], cwd=tree, env=env, capture_output=True, text=True, timeout=timeout)


def _files(tree):
    return [p for p in tree.rglob("*") if p.is_file()]


# ---------------------------------------------------------------- what the tree holds


def test_tree_leaves_out_the_instructors_files(tree):
    for rel_path in ("solutions", "tests", ".ci", ".git", ".venv", "out", "autograder/mistakes",
                     "autograder/oracle.py", "autograder/release"):
        assert not (tree / rel_path).exists(), rel_path
    assert not list(tree.rglob("__pycache__")) and not list(tree.rglob("*.egg-info"))
    for path in _files(tree):
        head = path.read_bytes()[:4096].decode("utf-8", errors="replace").splitlines()[:5]
        assert "# RELEASE: omit" not in [line.strip() for line in head], path
        if path.suffix in (".py", ".md", ".ipynb", ".txt", ".json", ".toml", ""):
            lines = [line.strip() for line in path.read_text(errors="replace").splitlines()]
            assert rel.BEGIN not in lines, f"{path} holds a solution block"
    assert (tree / "autograder" / "expected").is_dir()  # the public checks' data ships


def test_tree_has_the_students_readme_makefile_and_exercises(tree):
    assert (tree / "README.md").read_text() == (TEMPLATES / "README.md").read_text()
    assert (tree / "Makefile").read_text() == (TEMPLATES / "Makefile").read_text()
    readme = (tree / "README.md").read_text()
    for words in ("make demo", "make check", "python -m autograder", "--only", "hidden", "make notebooks",
                  "../shared/data", "COURSE_DATA", "curve_model", "pose_graph_fast", "dogleg"):
        assert words in readme, words
    assert "solutions" not in readme and "make test" not in readme
    makefile = (tree / "Makefile").read_text()
    targets = set(re.findall(r"^([a-z]+):", makefile, flags=re.M))
    assert {"demo", "check", "notebooks", "clean"} <= targets
    assert "pytest" not in makefile
    assert "$(PY) -m autograder" in makefile
    expected = rel.render(REPO_ROOT / "solutions")
    assert {str(p.relative_to(tree / "exercises")) for p in _files(tree / "exercises")} == set(expected)


def test_makefile_targets_parse(tree):
    make = shutil.which("make")
    if make is None:
        pytest.skip("no make on this machine")
    out = subprocess.run([make, "-n", "demo", "check", "test", "notebooks", "clean"], cwd=tree,
                         capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    for words in ("-m venv .venv", "pip install --quiet -e \".[peers]\"", ".venv/bin/python -m course demo",
                  ".venv/bin/python -m autograder", "-m notebooks.build --execute", "rm -rf .venv"):
        assert words in out.stdout, words


def test_every_make_target_has_its_commands_without_make_in_the_readme(tree):
    makefile = (tree / "Makefile").read_text()
    targets = re.search(r"^\.PHONY: (.*)$", makefile, flags=re.M).group(1).split()
    readme = (tree / "README.md").read_text()
    without_make = readme[readme.index("### Without make"):readme.index("## Requirements")]
    rows = re.findall(r"^\| `make (\w+)`", without_make, flags=re.M)
    assert set(targets) - {"venv", "test"} == set(rows), (targets, rows)  # test: an alias of check


def test_cli_release_student_writes_the_templates(tmp_path):
    repo = tmp_path / "repo"
    for name in ("solutions", "exercises"):
        shutil.copytree(REPO_ROOT / name, repo / name, ignore=shutil.ignore_patterns("__pycache__"))
    (repo / "README.md").write_text("instructor\n")
    (repo / "autograder" / "mistakes").mkdir(parents=True)
    (repo / "autograder" / "mistakes" / "damping.py").write_text("WRONG = 1\n")
    (repo / "autograder" / "judge.py").write_text('"""Doc."""\n# RELEASE: omit\n')
    (repo / "autograder" / "report.py").write_text("# RELEASE: omit is said on line 2 of the oracle\n")
    assert main(["release", "--root", str(repo), "--student", str(tmp_path / "student")]) == 0
    student = tmp_path / "student"
    assert (student / "README.md").read_text() == (TEMPLATES / "README.md").read_text()
    assert not (student / "autograder" / "mistakes").exists()
    assert not (student / "autograder" / "judge.py").exists()
    assert (student / "autograder" / "report.py").is_file()  # the marker must be the whole line
    with pytest.raises(rel.ReleaseError, match="inside the repository"):
        rel.release(check=True, root=repo, student_dir=repo / "student")


# ---------------------------------------------------------------- it runs on its own


def test_tree_imports_its_own_course_and_no_solutions(tree, python):
    code = ("import course, exercises, autograder; print(course.__file__); print(exercises.__file__)\n"
            "try:\n    import solutions\nexcept ModuleNotFoundError:\n    print('no solutions')\n"
            "else:\n    print('solutions at', solutions.__file__)\n"
            "from course.core.impl import default_impl; print(default_impl())\n"
            "from notebooks import build; print(build.default_impl())")
    out = _run(python, tree, "-c", code)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == str(tree / "course" / "__init__.py")
    assert lines[1] == str(tree / "exercises" / "__init__.py")
    assert lines[2:] == ["no solutions", "exercises", "exercises"]


@pytest.mark.slow
def test_pytest_in_the_tree_lists_the_public_checks(tree, python):
    """The tree's pytest.ini wins over its pyproject.toml; bare ``pytest`` (the console script: its
    own folder first on sys.path, the package on PYTHONPATH as the editable install puts it) and
    ``python -m pytest`` both load the plugin and list exercises/'s public checks, with points."""
    assert (tree / "pytest.ini").read_text() == (TEMPLATES / "pytest.ini").read_text()
    assert not (tree / "tests").exists()
    from autograder.checks import all_checks

    script = Path(sys.executable).parent / "pytest"  # bare `pytest`, run by the tree's interpreter
    for command in (["-m", "pytest"], [str(script)]):
        out = _run(python, tree, *command, "--collect-only", timeout=120)
        assert out.returncode == 0, out.stdout + out.stderr
        assert "configfile: pytest.ini" in out.stdout and "testpaths: exercises" in out.stdout
        quiet = _run(python, tree, *command, "--collect-only", "-q", timeout=120)
        ids = [line for line in quiet.stdout.splitlines() if "::" in line]
        assert len(ids) == len(all_checks()) and not [i for i in ids if "hidden inputs" in i], quiet.stdout
        assert "exercises/damping.py::GavinType1: update (accepted step) [1 pt]" in ids


@pytest.mark.slow
def test_demo_with_the_stubs_names_the_todos(tree, python, tmp_path):
    """The curve's peers run the student's model too (no analytic copy of it in the tree): with the stubs
    every row of the curve names its TODO, and the demo still writes its files and exits 0."""
    out = _run(python, tree, "-m", "course", "demo", "--curve-only", "--repeat", "1", "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr
    assert "Traceback" not in out.stdout + out.stderr and "Warning" not in out.stderr
    assert "impl exercises" in out.stdout
    for backend, method in (("ours", "gauss-newton"), ("ours", "lm-type1"), ("ours", "lm-type2"), ("ours", "lm-type3"),
                            ("ours", "dogleg"), ("scipy", "lm"), ("scipy", "trf")):
        assert re.search(rf"^{backend} +{method} +not implemented: TODO curve_model\.residuals_and_jacobian$",
                         out.stdout, flags=re.M), method
    doc = json.loads((tmp_path / "out" / "curve.json").read_text())
    skipped = [r for r in doc["runs"] if r.get("not_run")]
    assert len(skipped) == len(doc["runs"]) and all(r["final_chi2"] is None for r in skipped)
    for name in ("curve_chi2.png", "curve_lambda.png", "curve_fit.png"):
        assert (tmp_path / "out" / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def solved_tree(tmp_path_factory):
    """A student tree whose exercises/ holds the reference (solutions/*.py copied in)."""
    tree = _write_tree(tmp_path_factory.mktemp("solved") / "tree")
    for path in (REPO_ROOT / "solutions").glob("*.py"):
        shutil.copyfile(path, tree / "exercises" / path.name)
    return tree


@pytest.mark.slow
def test_demo_with_the_reference_copied_in_converges(solved_tree, python, tmp_path):
    out = _run(python, solved_tree, "-m", "course", "demo", "--curve-only", "--repeat", "1",
               "--out", str(tmp_path / "out"))
    assert out.returncode == 0, out.stderr
    assert "not implemented" not in out.stdout
    doc = json.loads((tmp_path / "out" / "curve.json").read_text())
    best = min(r["final_chi2"] for r in doc["runs"] if r["backend"] != "ours")
    ours = {r["method"]: r["final_chi2"] for r in doc["runs"] if r["backend"] == "ours"}
    assert set(ours) == {"gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg"}
    for method, chi2 in ours.items():
        assert chi2 == pytest.approx(best, rel=1e-6), method


def _not_implemented_section(text):
    match = re.search(r"^Not implemented \((\d+)\):\n((?:  .*\n?)*)", text, flags=re.M)
    assert match, text
    lines = [line.strip() for line in match.group(2).splitlines()]
    assert len(lines) == int(match.group(1))
    return lines


@pytest.mark.slow
def test_autograder_in_the_tree(tree, solved_tree, python):
    """Stubs: 0 points and one line per TODO; the reference copied in: full public marks."""
    out = _run(python, tree, "-m", "autograder")
    assert "Traceback" not in out.stdout + out.stderr, out.stderr
    assert re.search(r"^Total: 0 / \d+", out.stdout, flags=re.M), out.stdout + out.stderr
    todos = _not_implemented_section(out.stdout)
    assert todos and len(todos) == len(set(todos)) and all(t.startswith("TODO ") for t in todos)
    assert "TODO curve_model.residuals_and_jacobian: not implemented" in todos
    named = set(re.findall(r"(TODO [\w.]+): not implemented", out.stdout))
    assert named == {t.split(":")[0] for t in todos}
    full = _run(python, solved_tree, "-m", "autograder")
    assert full.returncode == 0, full.stdout + full.stderr
    total = re.search(r"^Total: (\d+(?:\.\d+)?) / (\d+(?:\.\d+)?)", full.stdout, flags=re.M)
    assert total and float(total.group(1)) == float(total.group(2)) > 0, full.stdout


# ---------------------------------------------------------------- rows, tables and notebooks


def test_a_run_that_did_not_run_is_a_row():
    from course.app import compare

    row = RunResult.skipped("ours", "lm-type1", "not implemented: TODO damping.GavinType1.damping_diagonal")
    table = compare.format_table([row], title="t")
    assert table.splitlines()[-1].split(maxsplit=2) == [
        "ours", "lm-type1", "not implemented: TODO damping.GavinType1.damping_diagonal"]
    doc = json.dumps(compare.to_json("curve", [row]), allow_nan=False)
    assert json.loads(doc)["runs"][0]["not_run"].endswith("damping_diagonal")
    assert not_implemented_reason(NotImplementedError("TODO a.b: not implemented yet")) == \
        "not implemented: TODO a.b"


def test_rebuilding_a_notebook_keeps_the_answer_cells(tmp_path):
    from notebooks import build

    (path,) = build.build(out_dir=tmp_path, only=["chapter2"])
    nb = nbformat.read(path, as_version=4)
    cells = {c["id"]: c for c in nb.cells}
    assert build.ANSWER_TAG in cells["answer-1"].metadata["tags"]
    cells["answer-1"].source = "**Your answer to question 1:** the factorization, mostly."
    cells["title"].source = "edited by hand"  # not an answer cell: regenerated
    nbformat.write(nb, path)
    build.build(out_dir=tmp_path, only=["chapter2"])
    rebuilt = {c["id"]: c for c in nbformat.read(path, as_version=4).cells}
    assert rebuilt["answer-1"].source.endswith("the factorization, mostly.")
    assert rebuilt["answer-2"].source == cells["answer-2"].source
    assert rebuilt["title"].source != "edited by hand"


def test_notebook_sources_ship_and_build_in_the_tree(tree):
    from notebooks import build

    for path, source in build.NOTEBOOKS.items():
        shipped = tree / "notebooks" / source.name
        assert shipped.read_text() == source.read_text()
        assert (tree / "notebooks" / path.name).is_file()
    assert (tree / "course" / "notebook_helpers" / "common.py").is_file()


def test_notebooks_default_to_the_trees_implementation(tree, python):
    """The set-up cell's IMPL, run in the student tree's notebooks/ folder, is ``exercises``."""
    from notebooks import build

    # the set-up cell, as the kernel runs it
    code = next(c.source for c in build.read(build.NOTEBOOKS[build.CHAPTER1]).cells if c.id == "setup")
    out = subprocess.run([python, "-c", code + "\nprint(IMPL)"], cwd=tree / "notebooks", capture_output=True,
                         text=True, env={k: v for k, v in os.environ.items() if k != "COURSE_IMPL"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "exercises"
    out = subprocess.run([sys.executable, "-c", code + "\nprint(IMPL)"], cwd=REPO_ROOT / "notebooks",
                         capture_output=True, text=True,
                         env={k: v for k, v in os.environ.items() if k != "COURSE_IMPL"})
    assert out.stdout.strip() == "solutions", out.stderr


# ---------------------------------------------------------------- a core-only install


@pytest.fixture(scope="module")
def core_python(solved_tree, tmp_path_factory):
    """A fresh venv with the solved tree installed as a student on a machine without the
    peers' wheels gets it: ``pip install -e .`` (no ``peers`` extra), and no qdldl (as on
    CPython 3.15). Needs the package index (CI has it).

    This venv's pip installs into it (``pip --python``): the same ``pip install -e .``, without
    seeding the new venv with a pip of its own first (ensurepip, a quarter of the set-up)."""
    folder = tmp_path_factory.mktemp("core-venv")
    folder.chmod(0o755)  # as root, the autograder's children run as another user
    env_dir = folder / "venv"
    venv.create(env_dir, with_pip=False)
    exe = str(env_dir / "bin" / "python")
    pip = [sys.executable, "-m", "pip", "--python", exe]
    install = subprocess.run([*pip, "install", "--quiet", "--no-compile", "-e", str(solved_tree)],
                             capture_output=True, text=True, timeout=900)
    if install.returncode != 0 and "NewConnectionError" in install.stdout + install.stderr:
        pytest.skip("the package index is not reachable here")
    assert install.returncode == 0, install.stdout + install.stderr
    subprocess.run([*pip, "uninstall", "--quiet", "--yes", "qdldl"], check=True, capture_output=True)
    assert subprocess.run([exe, "-c", "import qdldl"], capture_output=True).returncode != 0
    return exe


def _core_run(python, tree, *args):

    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL"))}
    env["COURSE_DATA"] = str(data_dir())  # intel in the demo where the data folder is
    return subprocess.run([python, *args], cwd=tree, env=env, capture_output=True, text=True, timeout=900)


@pytest.mark.slow
def test_a_core_only_install_runs_the_demo_and_says_once_what_is_missing(core_python, solved_tree, tmp_path):
    from course.core import peers

    out = _core_run(core_python, solved_tree, "-m", "course", "demo", "--repeat", "1", "--out", str(tmp_path))
    assert out.returncode == 0, out.stdout + out.stderr
    for library in ("pyceres", "g2opy", "gtsam", "qdldl"):
        assert out.stderr.count(peers.missing_message(library)) == 1, out.stderr
    assert "Traceback" not in out.stdout + out.stderr
    assert "not run: pyceres is not installed here" in out.stdout and "w10000 skipped" in out.stdout
    assert "not implemented" not in out.stdout


@pytest.mark.slow
def test_a_core_only_install_grades_all_but_the_checks_that_need_a_missing_library(core_python, solved_tree):
    from course.core import peers

    out = _core_run(core_python, solved_tree, "-m", "autograder", "--json", "results.json")
    assert out.returncode == 0, out.stdout + out.stderr
    for library in ("pyceres", "qdldl"):
        assert out.stderr.count(peers.missing_message(library)) == 1, out.stderr
    tests = json.loads((solved_tree / "results.json").read_text())["tests"]
    lost = {t["name"] for t in tests if t["score"] < t["max_score"]}
    assert lost == {t["name"] for t in tests if t["output"].startswith("not run: ")}
    assert {name.split(": ")[0] for name in lost} == {"ceres_edge_cost.SE2EdgeCost",
                                                      "sparse_solve.SparseCholeskySolver"}


# ---------------------------------------------------------------- no instructor words, and data it can get

#: words that are the instructor's alone: the reference's folder, its markers, notes to instructors, the release
INSTRUCTOR_WORDS = ("solutions/", rel.BEGIN, rel.END, "Instructors:", "python -m course release")


def test_what_a_student_reads_has_no_instructor_words(tree):
    """exercises/, notebooks/ (sources and shipped notebooks, outputs included), course/ and the README."""
    found = []
    paths = [tree / "README.md"] + [p for folder in ("exercises", "notebooks", "course")
                                    for p in _files(tree / folder)]
    for path in paths:
        text = path.read_text(errors="replace")
        for number, line in enumerate(text.splitlines(), start=1):
            found += [f"{path.relative_to(tree)}:{number}: {word!r}" for word in INSTRUCTOR_WORDS if word in line]
    assert not found, "\n".join(found)
    assert not (tree / "autograder" / "release").exists()  # the release tooling is the instructor's
    assert (tree / "exercises" / "__init__.py").read_text().startswith('"""Your implementations')


def test_the_students_command_line_has_no_release(tree, python, tmp_path):
    out = _run(python, tree, "-m", "course", "--help")
    assert out.returncode == 0, out.stderr
    assert "release" not in out.stdout and "compare" in out.stdout
    assert "release" in subprocess.run([sys.executable, "-m", "course", "--help"], cwd=REPO_ROOT,
                                       capture_output=True, text=True).stdout
    direct = _run(python, tree, "-m", "autograder", "release")
    assert direct.returncode == 2 and "the instructor's" in direct.stderr, direct.stderr
    assert "--gradescope" in subprocess.run([sys.executable, "-m", "autograder", "release", "--help"], cwd=REPO_ROOT,
                                            capture_output=True, text=True).stdout


def test_the_students_pyproject_registers_no_release(tree):
    """The instructor's ``pyproject.toml`` registers ``release`` (an entry point of ``course.commands``); the
    student's, every other line the same, registers nothing a student tree does not hold."""
    from autograder.release.carried_config import tomllib

    ours = tomllib.loads((REPO_ROOT / "pyproject.toml").read_text())
    theirs = tomllib.loads((tree / "pyproject.toml").read_text())
    assert ours["project"]["entry-points"]["course.commands"]["release"] == "autograder.release.command:add_parser"
    assert "entry-points" not in theirs["project"]
    ours["project"].pop("entry-points")
    assert ours == theirs


def test_missing_data_says_how_to_get_it_and_what_works_without(tree, python, tmp_path):
    env_data = str(tmp_path / "absent")
    run = lambda *args: subprocess.run(  # noqa: E731
        [python, "-m", "course", *args], cwd=tree, capture_output=True, text=True, timeout=300,
        env={**{k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL"))},
             "PYTHONPATH": str(tree), "COURSE_DATA": env_data})
    out = run("compare", "intel")
    assert out.returncode == 1
    for words in ("data folder", "not found", "your instructor ships it", "COURSE_DATA", "python -m course demo",
                  "compare curve"):
        assert words in out.stderr, (words, out.stderr)
    listing = run("datasets")
    assert listing.returncode == 0 and "your instructor ships it" in listing.stdout


@pytest.mark.slow
def test_with_chapter_1_written_every_notebook_is_written_and_chapter_1_runs_whole(python):
    """A student who has written chapter 1 alone: ``make notebooks`` (here its command, quick setting)
    writes every notebook and exits 0; chapter 1's runs every cell, its check cells included; no
    notebook shows a traceback (each lesson's tests read its own notebook from the same build)."""
    built = chapter_1_student_build(python)
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-6000:]
    assert len(list(out.glob("*.ipynb"))) == len(NOTEBOOKS) == 9
    assert re.search(r"chapter1_curve_fitting\.ipynb: all \d+ code cells ran", built["output"])
    text = (out / "chapter1_curve_fitting.ipynb").read_text()
    assert "every chi2 the C++ run prints is ours: True" in text
    for path in out.glob("*.ipynb"):
        assert "Traceback" not in path.read_text(), path.name
