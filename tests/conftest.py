"""Shared test fixtures."""

import os

import pytest

# Under pytest-xdist each worker grades with uids of its own (autograder.isolation.FIRST_ID), so
# that a test counting the processes left by its grading run never sees another worker's.
_WORKER = os.environ.get("PYTEST_XDIST_WORKER", "")
if _WORKER.startswith("gw") and _WORKER[2:].isdigit():
    os.environ["AUTOGRADER_FIRST_ID"] = str(61700 + 200 * int(_WORKER[2:]))


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


def pytest_collection_modifyitems(items):
    """A test that reads the batch grading of a module's variants (the ``graded`` fixture) is a
    real grading run: slow."""
    for item in items:
        if "graded" in getattr(item, "fixturenames", ()):
            item.add_marker(pytest.mark.slow)
