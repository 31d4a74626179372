"""The Gradescope bundle (``python -m course release --gradescope FILE.zip``): its
members, and ``run_autograder`` run end to end on an unpacked copy with the reference, the
stubs and a hostile submission, as Gradescope would (without setup.sh: this venv's
python3 stands in for the image's)."""

import json
import os
import stat
import subprocess
import sys
import zipfile

import pytest
from conftest import gradescope_zip

from autograder import submission as uploads
from autograder.oracle import CACHE_VARIABLE
from autograder.release import gradescope
from course.core.impl import REPO_ROOT

SCRIPTS = ("setup.sh", "run_autograder", "requirements.txt")
PINS = ("numpy==", "scipy==", "qdldl==", "pyceres==", "threadpoolctl==")
NOT_FOR_GRADING = ("g2opy", "gtsam", "matplotlib", "nbclient")
VISIBILITIES = {"visible", "hidden", "after_due_date", "after_published"}


def _number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def assert_gradescope_results(data) -> None:
    """The fields of Gradescope's results.json specification, with their types."""
    assert isinstance(data, dict)
    assert _number(data["score"])
    assert _number(data["execution_time"])
    assert isinstance(data["output"], str)
    assert isinstance(data["tests"], list)
    for test in data["tests"]:
        assert isinstance(test["name"], str) and test["name"]
        assert _number(test["score"]) and _number(test["max_score"])
        assert isinstance(test["output"], str)
        assert test["visibility"] in VISIBILITIES


# ---------------------------------------------------------------- the zip


@pytest.fixture(scope="module")
def bundle(tmp_path_factory):
    """The zip built by the CLI from a copy of this tree, and what runs it (``conftest.gradescope_zip``)."""
    base = tmp_path_factory.mktemp("gradescope")
    target = base / "out" / "autograder.zip"
    for built in gradescope_zip(base, target, timeout=120):
        assert f"wrote the Gradescope autograder to {target}" in built["stdout"] and "MiB" in built["stdout"]
        yield built


def test_each_bundle_draws_its_own_hidden_seed(tmp_path):
    seeds = []
    for k, seed in enumerate((None, None, 1234)):
        path = gradescope.build_bundle(tmp_path / f"b{k}.zip", hidden_seed=seed).path
        with zipfile.ZipFile(path) as archive:
            seeds.append(int(archive.read(gradescope.SEED_FILE)))
    assert seeds[0] != seeds[1] and seeds[2] == 1234
    script = (gradescope.TEMPLATES / "run_autograder").read_text()
    assert "export AUTOGRADER_HIDDEN_SEED" in script


def test_members(bundle):
    with zipfile.ZipFile(bundle["zip"]) as archive:
        infos = {info.filename: info for info in archive.infolist()}
        requirements = archive.read("requirements.txt").decode()
        setup = archive.read("setup.sh").decode()
    names = set(infos)
    for script in SCRIPTS:
        assert script in names
    for script in ("setup.sh", "run_autograder"):
        mode = infos[script].external_attr >> 16
        assert stat.S_ISREG(mode) and mode & 0o111 == 0o111, f"{script} is not executable ({oct(mode)})"
    assert infos["course/app/cli.py"].external_attr >> 16 & 0o111 == 0
    tops = {name.split("/")[0] for name in names}
    assert tops == set(SCRIPTS) | {"course", "autograder", "solutions", "exercises", "pyproject.toml",
                                   gradescope.SEED_FILE}
    for clutter in ("tests", ".git", ".venv", "notebooks", "__pycache__", ".pytest_cache"):
        assert not any(clutter in name.split("/") for name in names), clutter
    assert not any(name.endswith(".pyc") or ".egg-info" in name for name in names)
    for needed in ("solutions/damping.py", "exercises/damping.py", "exercises/__init__.py",
                   "autograder/oracle.py", "autograder/mistakes/damping.py", "autograder/expected/damping.json",
                   "autograder/__main__.py", "autograder/release/gradescope.py",
                   "autograder/release/gradescope_bundle/run_autograder"):
        assert needed in names, needed
    pins = [line.strip() for line in requirements.splitlines() if line.strip() and not line.startswith("#")]
    for pin in PINS:
        assert any(line.startswith(pin) for line in pins), pin
    assert all("==" in line for line in pins)
    assert not any(peer in line for line in pins for peer in NOT_FOR_GRADING)
    commands = [line for line in setup.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    assert any("pip install" in line and "requirements.txt" in line for line in commands)
    assert not any("apt-get" in line for line in commands)


def test_bundle_refuses_what_gradescope_cannot_take(tmp_path):
    with pytest.raises(gradescope.BundleError, match="zip"):
        gradescope.build_bundle(tmp_path / "autograder.tar", REPO_ROOT)
    run = subprocess.run([sys.executable, "-m", "course", "release", "--root", str(tmp_path / "nowhere"),
                          "--gradescope", str(tmp_path / "b.zip")], cwd=REPO_ROOT, capture_output=True, text=True)
    assert run.returncode == 2 and not (tmp_path / "b.zip").exists()

# ---------------------------------------------------------------- end to end


def start_autograder(bundle, name, submission_files, setup=None):
    """Unpack the zip into a fresh ROOT/source, place ``submission_files`` ({relative path:
    text}) in ROOT/submission and start ``bash run_autograder``; return (ROOT, process)."""
    root = bundle["roots"] / name
    (root / "submission").mkdir(parents=True)
    with zipfile.ZipFile(bundle["zip"]) as archive:
        archive.extractall(root / "source")
    for rel, text in submission_files.items():
        path = root / "submission" / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text.replace("@ROOT@", str(root)))
    if setup:
        setup(root)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "AUTOGRADER"))}
    env["AUTOGRADER_ROOT"] = str(root)
    if CACHE_VARIABLE in os.environ:  # the test run's cache: the runs of one bundle share its seed's data
        env[CACHE_VARIABLE] = os.environ[CACHE_VARIABLE]
    env["PATH"] = f"{bundle['bin']}{os.pathsep}{env.get('PATH', '/usr/bin:/bin')}"
    process = subprocess.Popen(["bash", str(root / "source" / "run_autograder")], cwd=str(root), env=env,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return root, process


def collect(root, process):
    """Wait for ``run_autograder``; return (ROOT, results.json, its output)."""
    try:
        out, err = process.communicate(timeout=300)
    except subprocess.TimeoutExpired:
        process.kill()
        out, err = process.communicate()
        pytest.fail(f"run_autograder in {root} took more than 300 s\n{out[-2000:]}{err[-2000:]}")
    assert process.returncode == 0, out[-2000:] + err[-2000:]
    results = json.loads((root / "results" / "results.json").read_text())
    assert_gradescope_results(results)
    return root, results, out + err


def run_autograder(bundle, name, submission_files, setup=None):
    return collect(*start_autograder(bundle, name, submission_files, setup))


def _exercise_files(folder: str, prefix: str) -> dict:
    return {f"{prefix}{path.name}": path.read_text() for path in sorted((REPO_ROOT / folder).glob("*.py"))
            if path.name != "__init__.py"}


@pytest.mark.slow
def test_reference_in_a_subfolder_gets_full_marks(bundle):
    _, results, run = run_autograder(bundle, "reference", _exercise_files("solutions", "my_work/"))
    maximum = sum(t["max_score"] for t in results["tests"])
    assert maximum > 0 and results["score"] == pytest.approx(maximum), results["output"]
    assert all(t["score"] == pytest.approx(t["max_score"]) for t in results["tests"])
    assert "my_work/" in results["output"]
    assert {t["visibility"] for t in results["tests"]} <= {"visible", "after_published"}


#: appended to the reference's damping.py (which deserves the damping points): at import
#: time it tries to overwrite the results and the code that runs as root after grading
HOSTILE_WRITER = '''
_ROOT = "@ROOT@"
for _path in (_ROOT + "/results/results.json", _ROOT + "/results/other.json"):
    try:
        with open(_path, "w") as _handle:
            _handle.write('{"score": 1000, "output": "pwned", "tests": []}')
    except OSError as _exc:
        print("could not write", _path, _exc)
for _path in (_ROOT + "/source/autograder/release/gradescope.py", _ROOT + "/source/autograder/report.py"):
    try:
        with open(_path, "a") as _handle:
            _handle.write("\\nraise SystemExit('pwned')\\n")
    except OSError as _exc:
        print("could not write", _path, _exc)
'''
#: appended to the stub of dogleg.py (which deserves nothing): it tries to read the reference (running it
#: would take ``exec``, which the grader refuses before the file runs); no import statement, which it would too
HOSTILE_READER = '''
for _path in ("@ROOT@/source/solutions/dogleg.py", "@ROOT@/source/autograder/oracle.py"):
    try:
        with open(_path) as _handle:
            print("READ-THE-REFERENCE", len(_handle.read()))
    except Exception as _exc:
        print("could not read", _path, _exc)
'''


@pytest.fixture(scope="module")
def stub_runs(bundle):
    """The stubs, and the stubs with a hostile damping.py, graded at the same time (both
    score 0 whatever the contention does to them; it saves half a minute)."""
    stubs = _exercise_files("exercises", "")
    hostile = dict(stubs)
    hostile["damping.py"] = (REPO_ROOT / "solutions" / "damping.py").read_text() + HOSTILE_WRITER
    hostile["dogleg.py"] = stubs["dogleg.py"] + HOSTILE_READER
    started = {"stubs": start_autograder(bundle, "stubs", stubs),
               "hostile": start_autograder(bundle, "hostile", hostile)}
    return {name: collect(*run) for name, run in started.items()}


@pytest.mark.slow
def test_stubs_score_zero(stub_runs):
    _, results, _ = stub_runs["stubs"]
    assert results["tests"] and results["score"] == 0
    assert "top level of the submission" in results["output"]


@pytest.mark.slow
def test_hostile_submission_gets_what_it_deserves(bundle, stub_runs):
    root, results, _ = stub_runs["hostile"]
    assert results["tests"], results["output"]
    assert "pwned" not in json.dumps(results) and "READ-THE-REFERENCE" not in json.dumps(results)
    damping = [t for t in results["tests"] if t["name"].startswith("damping.")]
    dogleg = [t for t in results["tests"] if t["name"].startswith("dogleg.")]
    assert damping and dogleg
    # the hostile module ran (its damping is the reference's) ...
    assert all(t["score"] == pytest.approx(t["max_score"]) for t in damping), \
        [t for t in damping if t["score"] != t["max_score"]]
    # ... and earned nothing else: the reference's dogleg was out of its reach
    assert results["score"] == pytest.approx(sum(t["max_score"] for t in damping)), \
        [t["name"] for t in results["tests"] if t["score"] and t not in damping]
    assert not (root / "results" / "other.json").exists()
    with zipfile.ZipFile(bundle["zip"]) as archive:
        for name in ("autograder/release/gradescope.py", "autograder/report.py"):
            assert (root / "source" / name).read_bytes() == archive.read(name), name


@pytest.mark.slow
def test_a_lazy_submission_is_refused_file_by_file(bundle):
    """The lazy folder (every exercise calling the framework's code, tests/student_variants/lazy.py) scores 0."""
    from student_variants.lazy import LAZY, lazy_text

    files = {f"{m}.py": lazy_text((REPO_ROOT / "exercises" / f"{m}.py").read_text(), m) for m in LAZY}
    _, results, _ = run_autograder(bundle, "lazy", files)
    assert results["tests"] and results["score"] == 0
    assert all("refused before running" in t["output"] for t in results["tests"]), \
        [t["name"] for t in results["tests"] if "refused before running" not in t["output"]][:5]
    edge = next(t for t in results["tests"] if t["name"].startswith("pose_graph_edge."))
    assert "pose_graph_edge.py:" in edge["output"] and "Allowed: numpy, scipy;" in edge["output"]


def test_no_exercise_files_gives_a_message(bundle):
    _, results, _ = run_autograder(bundle, "empty", {"notes/readme.txt": "hello", "main.py": "print(1)"})
    assert results["score"] == 0 and results["tests"] == []
    assert "No exercise file found" in results["output"]
    assert "damping.py" in results["output"] and "notes/readme.txt" in results["output"]


def test_a_crash_of_the_grader_still_gives_results(bundle):
    def break_grader(root):
        main = root / "source" / "autograder" / "__main__.py"
        main.write_text('raise RuntimeError("the grader broke")\n')

    _, results, _ = run_autograder(bundle, "crash", _exercise_files("solutions", ""), setup=break_grader)
    assert results["score"] == 0 and results["tests"] == []
    assert "the grader broke" in results["output"]
    assert "not a grade of your work" in results["output"]


# ---------------------------------------------------------------- the locator


MODULES = uploads.exercise_modules(REPO_ROOT)


def test_locator_finds_a_subfolder_without_init(tmp_path):
    work = tmp_path / "submission" / "my_work"
    work.mkdir(parents=True)
    (work / "damping.py").write_text("x = 1\n")
    (work / "curve_model.py").write_text("y = 2\n")
    (tmp_path / "submission" / "curve_model.py").write_text("older\n")  # fewer files at the top
    (tmp_path / "submission" / "__MACOSX").mkdir()
    for name in ("damping.py", "curve_model.py", "dogleg.py"):
        (tmp_path / "submission" / "__MACOSX" / name).write_text("resource fork\n")
    located = uploads.locate_submission(tmp_path / "submission", MODULES)
    assert located.folder == work
    assert located.found == ["curve_model.py", "damping.py"]
    assert "my_work/" in located.message and "graded as the unwritten stubs" in located.message


def test_locator_top_level_and_symlinks(tmp_path):
    submission = tmp_path / "submission"
    submission.mkdir()
    (submission / "gauss_newton.py").write_text("x = 1\n")
    (submission / "damping.py").symlink_to(REPO_ROOT / "solutions" / "damping.py")
    located = uploads.locate_submission(submission, MODULES)
    assert located.folder == submission and located.found == ["gauss_newton.py"]
    assert "top level" in located.message


def test_locator_without_exercise_files(tmp_path):
    submission = tmp_path / "submission"
    (submission / "stuff").mkdir(parents=True)
    (submission / "stuff" / "homework.py").write_text("x = 1\n")
    located = uploads.locate_submission(submission, MODULES)
    assert located.folder is None
    assert "No exercise file found" in located.message and "stuff/homework.py" in located.message
    assert "damping.py" in located.message
    empty = uploads.locate_submission(tmp_path / "missing", MODULES)
    assert empty.folder is None and "empty" in empty.message


def test_staging_copies_only_exercise_modules(tmp_path):
    work = tmp_path / "submission" / "hw"
    work.mkdir(parents=True)
    (work / "damping.py").write_text("MINE = True\n")
    (work / "course.py").write_text("shadow = True\n")
    (work / "numpy.py").write_text("shadow = True\n")
    (work / "autograder").mkdir()
    (work / "autograder" / "__init__.py").write_text("shadow = True\n")
    located = uploads.locate_submission(tmp_path / "submission", MODULES)
    staged = uploads.stage_submission(located, REPO_ROOT, tmp_path / "staged")
    names = sorted(p.name for p in staged.iterdir())
    assert names == sorted(MODULES + ["__init__.py"])
    assert (staged / "damping.py").read_text() == "MINE = True\n"
    assert (staged / "dogleg.py").read_text() == (REPO_ROOT / "exercises" / "dogleg.py").read_text()
    assert (staged / "__init__.py").read_text() == (REPO_ROOT / "exercises" / "__init__.py").read_text()


def test_finish_replaces_invalid_results(tmp_path):
    results = tmp_path / "results.json"
    results.write_text('{"score": "lots"}')
    log = tmp_path / "stderr.txt"
    log.write_text("Traceback ...\nValueError: oops\n")
    data = gradescope.finish(results, "Graded x.", "0", log, started=None)
    assert_gradescope_results(data)
    assert data["score"] == 0 and "oops" in data["output"]
    assert json.loads(results.read_text()) == data
    data = gradescope.finish(tmp_path / "none.json", "", "2", log)
    assert_gradescope_results(data)
    assert "status 2" in data["output"]
