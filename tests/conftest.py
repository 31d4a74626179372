"""Shared test fixtures."""

import pytest


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
