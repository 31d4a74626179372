"""Shared test fixtures."""

import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import venv
from pathlib import Path

import pytest

# Under pytest-xdist each worker grades with uids of its own (autograder.isolation.FIRST_ID), so
# that a test counting the processes left by its grading run never sees another worker's.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw") and _WORKER[2:].isdigit():
    os.environ["AUTOGRADER_FIRST_ID"] = str(61700 + 200 * int(_WORKER[2:]))


@pytest.fixture(scope="session", autouse=True)
def oracle_cache(tmp_path_factory):
    """The reference's data (``autograder.oracle.compute``) kept for the whole run, shared by the xdist
    workers and every grading process they start: the hidden data of one seed is computed once, not
    once per grading run. Its key holds the calls' inputs, the sources and numpy's build; a test that
    swaps what the reference computes with (a LAPACK driver) unsets it."""
    from autograder.oracle import CACHE_VARIABLE

    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / "oracle-cache"
    folder.mkdir(exist_ok=True)
    before = os.environ.get(CACHE_VARIABLE)
    os.environ[CACHE_VARIABLE] = str(folder)
    yield folder
    if before is None:
        os.environ.pop(CACHE_VARIABLE, None)
    else:
        os.environ[CACHE_VARIABLE] = before


@pytest.fixture(scope="session", autouse=True)
def shared_notebooks(tmp_path_factory):
    """Where the xdist workers of a run share their executed notebooks (``executed_notebooks.SHARED``): pytest's
    temporary folder of the run, removed with the older runs' (a folder of its own in /tmp stayed, 31 MB a run)."""
    import executed_notebooks

    if os.environ.get("PYTEST_XDIST_WORKER"):
        executed_notebooks.SHARED = tmp_path_factory.getbasetemp().parent / "executed-notebooks"


@pytest.fixture
def data_folder():
    """The shared data folder (``course.core.data.data_dir()``); skip when it is absent."""
    from course.core.data import data_dir

    folder = data_dir()
    if not folder.is_dir():
        pytest.skip(f"data folder {folder} not found (set COURSE_DATA to use another)")
    return folder


def needs(*libraries):
    """A mark that skips a test, naming the first of ``libraries`` not installed here.

    The peers (pyceres, g2opy, gtsam) come with the ``peers`` extra and only where they
    have wheels, qdldl not on every Python: a core-only install skips these tests."""
    from course.core import peers

    missing = [name for name in libraries if not peers.installed(name)]
    reason = f"{', '.join(missing)} not installed here (the peers extra, where it has wheels)"
    return pytest.mark.skipif(bool(missing), reason=reason)


def kernel_path(compiled: bool, monkeypatch) -> None:
    """Run the framework's kernels compiled by numba (skipped where numba is not installed) or by
    their numpy path (``COURSE_NO_JIT=1``), for the rest of the test."""
    from course.core import jit, peers

    if compiled:
        if not peers.installed("numba"):
            pytest.skip(peers.missing_message("numba"))
        monkeypatch.delenv(jit.NO_JIT, raising=False)
    else:
        monkeypatch.setenv(jit.NO_JIT, "1")


def pytest_collection_modifyitems(items):
    """A test that reads the batch grading of a module's variants (the ``graded`` fixture) is a
    real grading run: slow."""
    for item in items:
        if "graded" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="module")
def python():
    """An interpreter with this venv's packages but without the editable install (no ``solutions``
    on its path: a student's tree is what it finds first).

    It lives in a folder every user can search: as root, the autograder runs students'
    code as an unprivileged user, who must be able to start this interpreter."""
    folder = Path(tempfile.mkdtemp(prefix="course-student-venv-"))
    folder.chmod(0o755)
    env_dir = folder / "venv"
    venv.create(env_dir, with_pip=False)
    exe = env_dir / "bin" / "python"
    purelib = subprocess.run([str(exe), "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
                             capture_output=True, text=True, check=True).stdout.strip()
    folders = dict.fromkeys([sysconfig.get_path("purelib"), sysconfig.get_path("platlib")])
    (Path(purelib) / "course_packages.pth").write_text("\n".join(folders) + "\n")
    yield str(exe)
    shutil.rmtree(folder, ignore_errors=True)


def gradescope_zip(base: Path, target: Path, *release_args: str, timeout: float = 180):
    """Build the Gradescope zip by the CLI from a copy of this tree in ``base/repo`` (so that the release
    step rewrites nothing here), with ``release_args``; yield ``{"zip", "roots", "bin", "stdout"}``:
    a root for the autograder runs that the children's unprivileged uid can traverse (as /autograder on
    Gradescope) and a ``python3`` on PATH for ``run_autograder``. For a module-scoped fixture."""
    from autograder.release import gradescope
    from course.core.impl import REPO_ROOT

    repo = base / "repo"
    repo.mkdir()
    for name in gradescope.SOURCE_PATHS:
        source = REPO_ROOT / name
        if source.is_dir():
            shutil.copytree(source, repo / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copyfile(source, repo / name)
    run = subprocess.run([sys.executable, "-m", "course", "release", "--root", str(repo), *release_args,
                          "--gradescope", str(target)], cwd=REPO_ROOT, capture_output=True, text=True,
                         timeout=timeout)
    assert run.returncode == 0, run.stdout + run.stderr
    roots = Path(tempfile.mkdtemp(prefix="gradescope-test-"))
    os.chmod(roots, 0o755)
    shim = base / "bin"
    shim.mkdir()
    # a wrapper, not a symlink: a symlink to the venv's python resolves to the base interpreter and leaves the venv
    (shim / "python3").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    (shim / "python3").chmod(0o755)
    yield {"zip": target, "roots": roots, "bin": shim, "stdout": run.stdout}
    shutil.rmtree(roots, ignore_errors=True)
