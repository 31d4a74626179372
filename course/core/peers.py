"""Which optional libraries are installed here, and the one line said when one is not.

The peers (pyceres, g2opy, gtsam, jax, pycolmap) and cvxopt (CHOLMOD, for large factorizations with
fill-in) come with the ``peers`` extra, and only where they publish wheels; qdldl, numba and
jupytext are core requirements with no wheel for every Python. A missing one is never a traceback: the
runs, checks or datasets that need it step aside, and :func:`announce` says so once per
process, on stderr.
"""

import importlib.util
import sys

EXTRA_HINT = 'pip install "slam-backend-course[peers]"'

#: library -> what it is for and what happens without it
LIBRARIES = {
    "pyceres": "Ceres' runs are skipped",
    "g2opy": "g2o's runs are skipped",
    "gtsam": "GTSAM's runs and the datasets in its wheel (w100, w10000) are skipped",
    "jax": "the jax back end's runs (factor graphs linearised by jax.jacfwd) are skipped",
    "pycolmap": "Ceres' bundle-adjustment runs are skipped",
    "qdldl": "the sparse solves use scipy's SuperLU instead",
    "numba": "the Schur complement's reduction uses scipy's block-sparse product instead (about 4 times slower)",
    "jupytext": "the notebooks run from their .ipynb files as shipped",
    "cvxopt": "large systems and the 3D outlier experiments factorize with the implementation's sparse solve "
              "instead of CHOLMOD (slower under fill-in)",
}
#: what installs a library where a wheel exists
INSTALL = {"pyceres": EXTRA_HINT, "g2opy": EXTRA_HINT, "gtsam": EXTRA_HINT, "jax": EXTRA_HINT, "pycolmap": EXTRA_HINT,
           "qdldl": "pip install qdldl", "numba": "pip install numba",
           "jupytext": "pip install jupytext", "cvxopt": EXTRA_HINT}

_announced: set = set()


def installed(library: str) -> bool:
    """Whether ``library`` can be imported here (found without importing it)."""
    try:
        return importlib.util.find_spec(library) is not None
    except (ImportError, ValueError):  # a parent package missing, or a module without a spec
        return False


def missing_message(library: str) -> str:
    """``"gtsam is not installed here: GTSAM's runs ... are skipped; `pip install ...`"``."""
    return f"{library} is not installed here: {LIBRARIES[library]}; `{INSTALL[library]}` where it has a wheel"


def announce(library: str, stream=None) -> None:
    """Print :func:`missing_message` once per process and library."""
    if library in _announced:
        return
    _announced.add(library)
    sys.stdout.flush()  # after what was printed before it, also when both streams are piped
    print(missing_message(library), file=stream or sys.stderr)


def announce_missing(libraries=tuple(LIBRARIES)) -> list:
    """Announce each of ``libraries`` not installed here (once per process); returns them."""
    missing = [name for name in libraries if not installed(name)]
    for name in missing:
        announce(name)
    return missing


class PeerMissing(ImportError):
    """A run or check needs a library that is not installed here."""

    def __init__(self, library: str):
        super().__init__(missing_message(library), name=library)
        self.library = library


def require(library: str) -> None:
    """Raise :class:`PeerMissing` (after announcing it once) unless ``library`` is installed."""
    if not installed(library):
        announce(library)
        raise PeerMissing(library)
