"""The data folders: the shared one (``$COURSE_DATA``, else ``<repo>/../shared/data``) and the
gtsam wheel's ``Data/`` (found without importing gtsam), and the lookup of a named file in them.
"""

import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

from course.core import peers
from course.core.errors import DatasetError, MissingDataError
from course.core.impl import REPO_ROOT

#: what runs without the data folder: generated data and the graphs in the gtsam wheel
WITHOUT_DATA = ("`python -m course demo`, `python -m course compare curve` (or manhattan:N, bal-synthetic:C:P, "
                "w10000, sphere_smallnoise), `python -m course vio` and `make notebooks` (each notebook skips what "
                "is missing)")


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


def missing_data_help() -> str:
    """How to get the data folder, and what works without it: the sentence every message about
    missing data ends with."""
    default = REPO_ROOT.parent / "shared" / "data"
    where = f"COURSE_DATA is {os.environ['COURSE_DATA']}" if os.environ.get("COURSE_DATA") else \
        f"the course looks for it at {default}, next to this folder"
    return (f"The data folder holds third-party datasets the course does not copy; your instructor ships it: "
            f"unpack it at {default}, or set the environment variable COURSE_DATA to where it is ({where}). "
            f"Without it these work: {WITHOUT_DATA}; `python -m course datasets` lists what is here")


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
            raise MissingDataError(f"{what}: data folder {folder} not found", missing_data_help())
    path = folder / rel
    if not exists(path):
        if where == "gtsam":
            raise MissingDataError(f"{what}: {path} not found in the gtsam wheel's {folder}")
        raise MissingDataError(f"{what}: {rel} not found in the data folder {folder}", missing_data_help())
    return path


def origin(where: str, rel: str) -> str:
    """Where a named file comes from, for listings."""
    return f"gtsam wheel Data/{rel}" if where == "gtsam" else f"data folder: {rel}"
