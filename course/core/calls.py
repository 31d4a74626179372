"""Which of an implementation's functions a run called: the code to blame when a run goes wrong.

``Recording(package)`` (a context manager; ``course.core.impl.Implementation.recording`` opens one)
wraps, for as long as it is open, every function and method defined in the implementation's
modules (the package's modules loaded so far, and those loaded while it is open): module
functions, the methods of its classes (static and class methods, ``__init__`` and the operators
included, properties not), and the references to them that its modules hold (``from .x import f``,
a module-level dict of functions). The first call of a wrapper records ``module.qualname`` and puts
the original back, so a run pays for the wrapper once per function, not per call (Ceres calls the
student's ``Evaluate`` once per edge and iteration). ``called`` lists the names in the order first
called; a function never called (a stub of a method the run does not use) is never in it. On
closing, every wrapper still in place is taken out.
"""

import functools
import sys
import types

#: the recordings open now, by package (one at a time per package)
ACTIVE: dict = {}


class Recording:
    """The functions of ``package`` (an implementation's package name) called while it is open."""

    def __init__(self, package: str):
        self.package = package
        self.called: dict = {}  # name -> None, in the order first called
        self._patched: list = []  # (owner, attribute or key, original, wrapper)
        self._seen_modules: set = set()

    # ------------------------------------------------------------------ the context

    def __enter__(self) -> "Recording":
        if self.package in ACTIVE:
            raise RuntimeError(f"{self.package}: a recording of its calls is open already")
        ACTIVE[self.package] = self
        self.instrument()
        return self

    def __exit__(self, *exc_info) -> None:
        ACTIVE.pop(self.package, None)
        for owner, key, original, wrapper in reversed(self._patched):
            _put_back(owner, key, original, wrapper)
        self._patched.clear()

    # ------------------------------------------------------------------ what it wraps

    def _name(self, function) -> str:
        """``module.qualname`` with the package left out (``pose_graph_fast.SparseAssembler.assemble``)."""
        module = function.__module__[len(self.package) + 1:]
        return f"{module}.{function.__qualname__}"

    def _own(self, function) -> bool:
        return isinstance(function, types.FunctionType) and \
            str(getattr(function, "__module__", "")).startswith(self.package + ".")

    def instrument(self) -> None:
        """Wrap what the package's modules loaded since the last call define (``impl.module`` calls this)."""
        prefix = self.package + "."
        for name in [n for n in list(sys.modules) if n.startswith(prefix) and n not in self._seen_modules]:
            module = sys.modules.get(name)
            if module is None:
                continue
            self._seen_modules.add(name)
            for key, value in list(vars(module).items()):
                if self._own(value):
                    self._wrap(module, key, value)
                elif isinstance(value, type) and value.__module__ == name:
                    self._wrap_class(value)
                elif isinstance(value, dict) and not key.startswith("__"):
                    for item_key, item in list(value.items()):
                        if self._own(item):
                            self._wrap(value, item_key, item)

    def _wrap_class(self, cls) -> None:
        for key, value in list(vars(cls).items()):
            if self._own(value):
                self._wrap(cls, key, value)
            elif isinstance(value, (staticmethod, classmethod)) and self._own(value.__func__):
                self._wrap(cls, key, value)

    def _wrap(self, owner, key, original) -> None:
        function = original.__func__ if isinstance(original, (staticmethod, classmethod)) else original
        name, called, patched = self._name(function), self.called, self._patched

        @functools.wraps(function)
        def first_call(*args, **kwargs):
            called.setdefault(name, None)
            _put_back(owner, key, original, wrapper)
            return function(*args, **kwargs)

        wrapper = type(original)(first_call) if isinstance(original, (staticmethod, classmethod)) else first_call
        _set(owner, key, wrapper)
        patched.append((owner, key, original, wrapper))

    @property
    def names(self) -> tuple:
        """The functions called, in the order first called."""
        return tuple(self.called)


def _set(owner, key, value) -> None:
    if isinstance(owner, dict):
        owner[key] = value
    else:
        setattr(owner, key, value)


def _put_back(owner, key, original, wrapper) -> None:
    """``original`` in place of ``wrapper``, unless something else replaced it since."""
    current = owner.get(key) if isinstance(owner, dict) else vars(owner).get(key)
    if current is wrapper:
        _set(owner, key, original)


def instrument(package: str) -> None:
    """Wrap the newly loaded modules of ``package`` when a recording of it is open (else nothing)."""
    recording = ACTIVE.get(package)
    if recording is not None:
        recording.instrument()
