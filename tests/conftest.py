"""Shared test fixtures."""

import pytest


@pytest.fixture
def data_folder():
    """The shared data folder (``course.datasets.data_dir()``); skip when it is absent."""
    from course.datasets import data_dir

    folder = data_dir()
    if not folder.is_dir():
        pytest.skip(f"data folder {folder} not found (set COURSE_DATA to use another)")
    return folder
