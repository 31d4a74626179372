"""The chapters and the framework each adds (course/core/chapters.py), and an assignment's tree that ships
the framework up to its chapter: a ch2 tree has no factor graph and no problems or peers of chapters 4-7,
every module it ships imports, and its commands say a later chapter is not handed out yet."""

import importlib
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from autograder.checks import ORDER
from autograder.course_config import load
from autograder.release import assignment as handout
from autograder.release.stubs import render
from course.core import chapters
from course.core.impl import REPO_ROOT

COURSE = load()
#: what a ch2 tree must not hold (the issue's list), and what it must
NOT_IN_CH2 = ("course/factorgraph", "course/backends/factorgraph", "course/problems/bal", "course/backends/bal",
              "course/problems/vio", "course/backends/vio", "course/problems/posegraph3d",
              "course/backends/posegraph3d", "course/problems/posegraph/factor_graph.py",
              "notebooks/chapter3_dogleg.py", "notebooks/chapter7_factor_graphs.ipynb",
              "course/notebook_helpers/chapter7.py", "course/app/benchmark_autodiff.py")
IN_CH2 = ("course/problems/curve", "course/backends/curve", "course/problems/posegraph", "course/backends/posegraph",
          "notebooks/chapter1_curve_fitting.py", "notebooks/chapter2_pose_graphs.ipynb", "course/solver",
          "course/notebook_helpers/common.py")


def test_every_exercise_is_in_one_chapter_and_the_default_assignments_are_the_chapters():
    held = [name for one in chapters.CHAPTERS for name in one.exercises]
    assert sorted(held) == sorted(ORDER) and len(held) == len(set(held))
    for name, assignment in COURSE.assignments.items():
        assert set(assignment.exercises) <= set(chapters.chapter(name).exercises), name


def test_every_family_and_notebook_belongs_to_one_chapter():
    """A new problem family, peer folder, notebook or chapter helper must be mapped here, or a tree of an
    earlier assignment would ship it."""
    claimed = [rel for one in chapters.CHAPTERS for rel in chapters.files(one)]
    assert len(claimed) == len(set(claimed))
    for one in chapters.CHAPTERS:
        for rel in one.paths:  # every path names something that is there
            assert (REPO_ROOT / rel).exists() or any(p.startswith(rel[:-1]) for p in chapters.files(one)), rel
    wanted = [f"course/{kind}/{p.name}" for kind in ("problems", "backends")
              for p in sorted((REPO_ROOT / "course" / kind).iterdir()) if p.is_dir() and p.name != "__pycache__"]
    wanted += [f"notebooks/{p.name}" for p in sorted((REPO_ROOT / "notebooks").glob("chapter*"))]
    wanted += [f"course/notebook_helpers/{p.name}" for p in sorted((REPO_ROOT / "course" / "notebook_helpers")
                                                                  .glob("chapter*.py"))]
    assert sorted(set(wanted) - set(claimed)) == []
    for kind in ("curve", "posegraph", "bal", "vio", "posegraph3d", "factorgraph"):
        assert chapters.of_family(kind).name in chapters.BY_NAME


def test_an_assignments_tree_drops_every_later_chapter():
    for name, assignment in COURSE.assignments.items():
        dropped = set(handout.dropped(COURSE, assignment))
        kept = chapters.up_to(handout.handed_out_exercises(COURSE, assignment))
        assert kept[-1].name == name  # the default course: one assignment per chapter
        for one in chapters.CHAPTERS:
            files = set(chapters.files(one))
            assert (files <= dropped) if one not in kept else not (files & dropped), (name, one.name)


@pytest.fixture(scope="module")
def ch2_tree(tmp_path_factory):
    target = tmp_path_factory.mktemp("ch2") / "tree"
    handout.write_student_tree(target, COURSE, COURSE.assignment("ch2"), render(REPO_ROOT / "solutions"))
    return target


def test_the_ch2_tree_ships_chapters_1_and_2_alone(ch2_tree):
    for rel in NOT_IN_CH2:
        assert not (ch2_tree / rel).exists(), rel
    for rel in IN_CH2:
        assert (ch2_tree / rel).exists(), rel
    assert chapters.handed_out("ch2", ch2_tree) and not chapters.handed_out("ch4", ch2_tree)
    assert not chapters.handed_out("ch7", ch2_tree) and chapters.handed_out("ch7")
    assert "This tree holds the course up to chapter 2 (2D pose graphs)" in (ch2_tree / "README.md").read_text()


def _run(python, tree, *args, timeout=600, **env):
    base = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL", "AUTOGRADER"))}
    base.update(PYTHONPATH=str(tree), **env)
    return subprocess.run([python, *args], cwd=tree, env=base, capture_output=True, text=True, timeout=timeout)


SCAN = """
import importlib, pathlib, sys
root = pathlib.Path.cwd()
failed = []
for path in sorted(root.rglob("*.py")):
    rel = path.relative_to(root)
    if rel.parts[0] in ("exercises", ".venv") or rel.name == "__main__.py" or "gradescope_bundle" in rel.parts \\
            or (rel.parts[0] == "notebooks" and rel.name.startswith("chapter")):
        continue
    name = ".".join(rel.with_suffix("").parts).removesuffix(".__init__")
    try:
        importlib.import_module(name)
    except Exception as exc:
        failed.append(f"{name}: {exc!r}")
print("\\n".join(failed) or "all imported")
"""


def test_every_module_of_the_ch2_tree_imports_and_later_chapters_are_named(ch2_tree, python):
    out = _run(python, ch2_tree, "-c", SCAN)
    assert out.stdout.strip() == "all imported", out.stdout + out.stderr
    for args, code, says in ((("compare", "ladybug-49"), 2, "not handed out yet in this tree: chapter 4's bal"),
                             (("compare", "sphere2500"), 2, "chapter 6's posegraph3d"),
                             (("vio",), 1, "vio needs chapter 5"), (("ape", "euroc-mh05"), 1, "ape needs chapter 5"),
                             (("outliers3d",), 1, "outliers3d needs chapter 6"),
                             (("benchmark", "--autodiff"), 1, "needs chapter 7")):
        run = _run(python, ch2_tree, "-m", "course", *args)
        assert run.returncode == code and says in run.stderr and "Traceback" not in run.stderr, (args, run.stderr)
    run = _run(python, ch2_tree, "-m", "course", "compare", "manhattan:30", "--backends", "ours-autodiff,jax",
               "--methods", "gauss-newton")
    assert run.returncode == 0, run.stderr
    assert len(re.findall(r"not run: back end \S+ needs chapter 7 .*not handed out yet", run.stdout)) == 2, run.stdout
    listing = _run(python, ch2_tree, "-m", "course", "datasets")
    assert listing.returncode == 0 and "intel" in listing.stdout and "ladybug" not in listing.stdout, listing.stdout


@pytest.mark.slow
@pytest.mark.parametrize("name", [name for name in COURSE.assignments if name != "ch2"])
def test_every_assignments_tree_imports_whole(name, python, tmp_path):
    target = tmp_path / "tree"
    handout.write_student_tree(target, COURSE, COURSE.assignment(name), render(REPO_ROOT / "solutions"))
    out = _run(python, target, "-c", SCAN)
    assert out.stdout.strip() == "all imported", out.stdout + out.stderr
    demo = _run(python, target, "-m", "course", "demo", "--curve-only", "--repeat", "1", "--out", str(tmp_path / "out"))
    assert demo.returncode == 0 and "Traceback" not in demo.stderr, demo.stderr


@pytest.mark.slow
def test_the_ch2_trees_readme_commands_work(ch2_tree, python, tmp_path):
    """What its README says a student runs: ``make demo`` (the chapters handed out so far, and a line for each
    later one) and ``make check`` (0 with the stubs, every public point with the reference copied in)."""
    readme = (ch2_tree / "README.md").read_text()
    assert "make demo" in readme and "make check" in readme
    no_data = {"COURSE_DATA": str(tmp_path / "no-data")}  # w10000 ships with gtsam; intel is skipped
    demo = _run(python, ch2_tree, "-m", "course", "demo", "--repeat", "1", "--out", str(tmp_path / "out"), **no_data)
    assert demo.returncode == 0 and "Traceback" not in demo.stdout + demo.stderr, demo.stdout[-3000:] + demo.stderr
    assert "Curve fit" in demo.stdout and "w10000" in demo.stdout
    assert "chapter 4 (bundle adjustment) is not handed out yet: skipped" in demo.stdout
    assert "chapter 6 (3D pose graphs) is not handed out yet: skipped" in demo.stdout
    todo_line = next(line for line in demo.stdout.splitlines() if "stopped at a TODO" in line)
    assert "dogleg" not in todo_line  # chapter 3's: nothing to write in this tree yet
    maximum = COURSE.assignment("ch2").maximum("public")
    stubs = _run(python, ch2_tree, "-m", "autograder")
    assert stubs.returncode == 0 and _total(stubs.stdout) == (0, maximum), stubs.stdout
    solved = tmp_path / "solved"
    shutil.copytree(ch2_tree, solved, ignore=shutil.ignore_patterns("__pycache__"))
    for module in COURSE.assignment("ch2").modules:
        shutil.copyfile(REPO_ROOT / "solutions" / f"{module}.py", solved / "exercises" / f"{module}.py")
    full = _run(python, solved, "-m", "autograder")
    score, out_of = _total(full.stdout)
    assert out_of == maximum and score >= maximum, full.stdout[-3000:]  # the optional exercise is extra credit


def test_a_chapter_not_handed_out_is_an_error_naming_it(monkeypatch):
    monkeypatch.setattr(chapters, "handed_out", lambda name, root=REPO_ROOT: name not in ("ch4", "ch5"))
    with pytest.raises(chapters.NotHandedOut, match=r"vio needs chapter 5 \(a visual-inertial back end\)"):
        chapters.require("ch5", "vio")
    compare = importlib.import_module("course.app.compare")
    with pytest.raises(compare.UnknownDatasetError, match="not handed out yet in this tree: chapter 4.s bal"):
        compare.find_runner("nothing-of-that-name")
    assert not Path(REPO_ROOT, "course", "solver", "per_pattern.py").exists()


# ---------------------------------------------------------------- the lazy folder: delegations to shipped code

#: exercise files that derive nothing: each hands the work to framework code a tree shipped before (the issue's
#: list). They must score what the stubs score: the code they call is gone, or not in the tree of the chapter.
LAZY = {
    # chapter 7's engine differentiates its own edge residual: not in a ch2 tree
    "pose_graph_edge.py": '''
import numpy as np
from course.factorgraph.factors import between_se2
from course.factorgraph.numeric import central_differences
from course.factorgraph.variables import SE2


def edge_error_and_jacobians(x_i, x_j, z_ij):
    z = np.asarray(z_ij, dtype=float)[None]
    r, (A, B) = central_differences(lambda a, b: between_se2(z, a, b), [SE2.retract, SE2.retract], [3, 3],
                                    [np.asarray(x_i, dtype=float)[None], np.asarray(x_j, dtype=float)[None]],
                                    step=1e-6)
    return r[0], A[0], B[0]
''',
    # the VIO window's dense Cholesky and the pattern check of a sparse solver: the implementation's now
    "sparse_solve.py": '''
import scipy.sparse as sp
from course.problems.vio.problem import _cholesky_solve
from course.solver.per_pattern import PerPattern


def dense_solve(H, b):
    return _cholesky_solve(H, -b)


def upper_triangle_csc(H):
    return sp.triu(sp.csc_matrix(H), format="csc")


class SparseCholeskySolver:
    def __init__(self):
        import qdldl

        class Once:
            def solve(self, H, b):
                return -qdldl.Solver(H, upper=True).solve(b)

        self._solver = PerPattern(Once)

    def solve(self, H_upper, b):
        return self._solver.solve(H_upper, b)
''',
    # the curve peer's analytic model (scipy's recorder): the peers run the implementation's model now
    "curve_model.py": '''
import numpy as np
from course.backends.curve.scipy import _Recorder


class _Data:
    def __init__(self, x, y):
        self.x, self.y, self.weights = x, y, np.ones_like(x)


def residuals_and_jacobian(params, x, y):
    recorder = _Recorder(_Data(np.asarray(x, dtype=float), np.asarray(y, dtype=float)))
    return recorder.residuals(np.asarray(params, dtype=float)), recorder.jacobian(np.asarray(params, dtype=float))
''',
    # the IMU factor's residual, which the analytic Jacobian's module computed "exactly": it computes none now
    "imu_preintegration.py": '''
import numpy as np
from course.geometry.so3 import so3_log
from course.problems.vio.imu_jacobians import imu_residual_jacobian


def imu_factor_residual(state_i, state_j, preintegrated, bias_i, gravity):
    (R_i, v_i, p_i), (R_j, v_j, p_j) = state_i, state_j
    s_i = np.r_[so3_log(R_i), p_i, v_i, bias_i[0], bias_i[1]]
    s_j = np.r_[so3_log(R_j), p_j, v_j, bias_i[0], bias_i[1]]
    return imu_residual_jacobian(s_i, s_j, tuple(preintegrated), gravity)[0]
''',
}


def _lazy_folder(target: Path, base: Path) -> Path:
    """``base``'s exercises/ with each lazy file appended to its stub (its definitions win; what the stub
    gives, such as ``Preintegrated``, stays)."""
    shutil.copytree(base, target, ignore=shutil.ignore_patterns("__pycache__"))
    for name, text in LAZY.items():
        stub = target / name
        stub.write_text((stub.read_text() if stub.exists() else "") + "\n" + text)
    return target


@pytest.fixture(scope="module")
def clean_python(tmp_path_factory):
    """An interpreter with this venv's packages but none of its editable installs: as in a student's own venv,
    nothing maps ``course.*`` to this repository (the grader's children add the borrowed site folders, whose
    editable-install finder would otherwise find ``course.factorgraph`` here for a tree that has none)."""
    import sysconfig
    import venv

    folder = tmp_path_factory.mktemp("clean-python")
    folder.chmod(0o755)
    packages = folder / "site-packages"
    packages.mkdir()
    for source in dict.fromkeys([sysconfig.get_path("purelib"), sysconfig.get_path("platlib")]):
        for entry in Path(source).iterdir():
            if not entry.name.startswith("__editable__") and not (packages / entry.name).exists():
                (packages / entry.name).symlink_to(entry)
    venv.create(folder / "venv", with_pip=False)
    exe = folder / "venv" / "bin" / "python"
    purelib = subprocess.run([str(exe), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                             capture_output=True, text=True, check=True).stdout.strip()
    (Path(purelib) / "course_packages.pth").write_text(f"{packages}\n")
    for path in (folder, packages):
        path.chmod(0o755)
    return str(exe)


def _total(text):
    found = re.search(r"^Total: (\d+(?:\.\d+)?) / (\d+(?:\.\d+)?)", text, flags=re.M)
    assert found, text[-3000:]
    return float(found.group(1)), float(found.group(2))


@pytest.mark.slow
def test_the_lazy_folder_scores_what_the_stubs_score(ch2_tree, clean_python, tmp_path):
    """In the ch2 tree (no chapter-7 engine there) and in the whole course for what no tree holds any more."""
    lazy = _lazy_folder(tmp_path / "lazy", ch2_tree / "exercises")
    graded = _run(clean_python, ch2_tree, "-m", "autograder", "--impl", str(lazy))
    assert _total(graded.stdout)[0] == 0, graded.stdout[-3000:]
    derived = tmp_path / "derived"  # the same interpreter grades a derived edge: the zero above is the lazy file's
    shutil.copytree(ch2_tree / "exercises", derived)
    shutil.copyfile(REPO_ROOT / "solutions" / "pose_graph_edge.py", derived / "pose_graph_edge.py")
    graded = _run(clean_python, ch2_tree, "-m", "autograder", "--impl", str(derived), "--only", "pose_graph_edge")
    score, out_of = _total(graded.stdout)
    assert score == out_of > 0, graded.stdout[-3000:]
    whole = _lazy_folder(tmp_path / "whole", REPO_ROOT / "exercises")
    for only in ("curve_model", "sparse_solve", "imu_preintegration.imu_factor_residual"):
        out = subprocess.run([os.sys.executable, "-m", "autograder", "--impl", str(whole), "--only", only],
                             cwd=REPO_ROOT, capture_output=True, text=True, timeout=600)
        assert _total(out.stdout)[0] == 0, out.stdout[-3000:]
