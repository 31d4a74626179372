"""Choose an implementation of the exercises by name.

``solutions`` is the reference, ``exercises`` the student's copy in this repository,
and any other string is a path to a directory laid out like ``exercises/`` (a student's
submission). Modules inside an implementation import each other relatively and the
framework absolutely (``from course import ...``), so any of them loads under any name.
"""

import hashlib
import importlib
import importlib.util
import sys
from pathlib import Path

from course.core import calls

REPO_ROOT = Path(__file__).resolve().parents[2]
BUILTIN = ("solutions", "exercises")


class Implementation:
    """A loaded implementation; ``impl.module("damping")`` imports one of its modules."""

    def __init__(self, name: str, package: str):
        self.name = name
        self.package = package

    def module(self, name: str):
        """The module ``name`` of this implementation. One it does not hold (an assignment's tree has no
        file of a later assignment) is an unwritten TODO: a ``NotImplementedError`` naming it."""
        try:
            module = importlib.import_module(f"{self.package}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{self.package}.{name}":
                raise
            raise NotImplementedError(f"TODO {name}: no {name}.py in this implementation "
                                      "(not handed out yet)") from None
        calls.instrument(self.package)
        return module

    def recording(self) -> calls.Recording:
        """A context that records which of this implementation's functions run while it is open
        (``course.core.calls``): ``with impl.recording() as run: ...; run.names``."""
        return calls.Recording(self.package)

    def __repr__(self):
        return f"Implementation({self.name!r})"


def load(name_or_path="solutions") -> Implementation:
    """Return the implementation called ``solutions``, ``exercises`` or at a path."""
    if isinstance(name_or_path, Implementation):
        return name_or_path
    name = str(name_or_path)
    if name in BUILTIN:
        if str(REPO_ROOT) not in sys.path:
            sys.path.insert(0, str(REPO_ROOT))
        importlib.import_module(name)
        return Implementation(name, name)
    path = Path(name).resolve()
    init = path / "__init__.py"
    if not path.is_dir() or not init.is_file():
        raise ValueError(
            f"--impl {name!r}: expected 'solutions', 'exercises' or a directory laid out "
            f"like exercises/ (with an __init__.py); {path} is not one"
        )
    package = "student_" + hashlib.sha1(str(path).encode()).hexdigest()[:10]
    if package not in sys.modules:
        spec = importlib.util.spec_from_file_location(
            package, init, submodule_search_locations=[str(path)]
        )
        assert spec is not None and spec.loader is not None  # a file location always has both
        module = importlib.util.module_from_spec(spec)
        sys.modules[package] = module
        spec.loader.exec_module(module)
    return Implementation(str(path), package)


def default_impl() -> str:
    """``solutions`` in the course repository, ``exercises`` in a student tree (which has no reference)."""
    return "solutions" if (REPO_ROOT / "solutions" / "__init__.py").is_file() else "exercises"


def not_implemented_reason(exc: NotImplementedError) -> str:
    """``"not implemented: TODO module.function"`` from a stub's error (or its own text)."""
    text = str(exc).strip()
    suffix = ": not implemented yet"
    if text.endswith(suffix):
        text = text[: -len(suffix)]
    return f"not implemented: {text}" if text else "not implemented"


def failure_reason(exc: Exception) -> str:
    """``"failed: ..."`` for a run that raised: the framework's own errors (``CourseError``) name the
    function already; any other error adds its type and the last line of the traceback that is not
    in the framework (the student's file and line, when the error is theirs)."""
    from course.core.errors import CourseError

    if isinstance(exc, CourseError):
        return f"failed: {exc}"
    import traceback

    framework = str(Path(__file__).resolve().parents[1])
    frames = [f for f in traceback.extract_tb(exc.__traceback__) if not f.filename.startswith(framework)]
    where = f" (at {frames[-1].filename}:{frames[-1].lineno})" if frames else ""
    return f"failed: {type(exc).__name__}: {exc}{where}"
