"""The data folders: the shared one (``$COURSE_DATA``, else ``<repo>/../shared/data``) and the
gtsam wheel's ``Data/`` (found without importing gtsam), and the lookup of a named file in them.
"""

import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

from course.core import peers
from course.core.errors import DatasetError
from course.core.impl import REPO_ROOT


@dataclass(frozen=True)
class DatasetInfo:
    """One named dataset: documented size, format, origin and availability."""

    name: str
    poses: int | None
    edges: int | None
    format: str
    origin: str
    available: bool
    reason: str = ""


def data_dir() -> Path:
    """The data folder: ``$COURSE_DATA`` if set, else ``<repo>/../shared/data``."""
    env = os.environ.get("COURSE_DATA")
    if env:
        return Path(env)
    return REPO_ROOT.parent / "shared" / "data"


def gtsam_data_dir() -> Path | None:
    """The gtsam wheel's ``Data`` folder (found without importing gtsam), or None."""
    try:
        spec = importlib.util.find_spec("gtsam")
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]) / "Data"


def locate(what: str, where: str, rel: str, exists=Path.is_file) -> Path:
    """The path of a named file: ``rel`` in the data folder (``where == "data"``) or in the gtsam
    wheel (``"gtsam"``); ``DatasetError`` naming ``what`` (e.g. ``"dataset 'intel'"``) when absent.

    ``exists(path)`` says whether the file is there (a TORO pair is found by its prefix)."""
    if where == "gtsam":
        folder = gtsam_data_dir()
        if folder is None:
            raise DatasetError(f"{what} ships with gtsam, which is not installed here "
                               f"(`{peers.EXTRA_HINT}` where it has a wheel)")
    else:
        folder = data_dir()
        if not folder.is_dir():
            raise DatasetError(f"{what}: data folder {folder} not found "
                               "(set the environment variable COURSE_DATA to a folder with the same layout)")
    path = folder / rel
    if not exists(path):
        raise DatasetError(f"{what}: {path} not found in {folder}")
    return path


def origin(where: str, rel: str) -> str:
    """Where a named file comes from, for listings."""
    return f"gtsam wheel Data/{rel}" if where == "gtsam" else f"data folder: {rel}"
