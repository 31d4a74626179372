"""The registry of checks, one module per chapter (``chapter1.py``, ``chapter2.py``, ...).

A check is a :class:`Check`: a ``name`` (unique, ``"<exercise>: <title>"``), the
``exercise`` it belongs to (partial credit per exercise is the sum of its checks),
``points``, ``calls`` (a function returning the list of :class:`Call` the child runs
with the student's implementation; pure inputs, no student code) and ``judge``, a
function in the parent that turns a :class:`Context` (the calls, the student's raw
outputs, the reference outputs computed in the parent from ``solutions``) into a
:class:`Verdict` (fraction of the points earned, feedback). Helpers for judges that
compare values with explicit rtol/atol are in :mod:`autograder.compare`.

To add a chapter, write ``autograder/checks/chapterN.py`` with two module attributes:
``MODULES`` (the implementation modules it grades, e.g. ``("pose_graph_edge",)``)
and ``CHECKS`` (a list of :class:`Check`). It is discovered by its file name; nothing
else changes. A call's ``target`` is ``"module:qualname"`` inside the implementation
(``"damping:GavinType1.update"``: the class is instantiated with ``init`` first), or
``"@package.module:function"`` for a framework function that the child calls with
``impl=<the student's implementation>`` (see :mod:`autograder.tasks`).
"""

import importlib
import pkgutil
from dataclasses import dataclass, field
from typing import Any, Callable, Optional


@dataclass(frozen=True)
class Call:
    """One call the child makes: ``target(*args, **kwargs)``.

    ``returns`` says how the raw output is read: a tuple of names for a tuple
    (``("r", "J")``), ``"state"`` for a ``DampingState`` (fields ``lam``, ``nu``),
    ``"value"`` for one array or scalar, ``"dict"`` for a framework task's dict of arrays.
    ``where`` describes the inputs in feedback ("at params (0, 0, 0)"); ``label``
    replaces the target's name in feedback.
    """

    target: str
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    init: dict = field(default_factory=dict)
    returns: Any = "value"
    where: str = ""
    label: str = ""  # how feedback names the call; default from target

    @property
    def function(self) -> str:
        """The name a student recognises: ``damping.GavinType1.update``."""
        if self.label:
            return self.label
        if self.target.startswith("@"):
            return self.target[1:].replace(":", ".")
        return self.target.replace(":", ".")

    def payload(self) -> dict:
        """What is pickled to the child (plain data, no classes of the autograder)."""
        return {"target": self.target, "args": self.args, "kwargs": self.kwargs, "init": self.init}


@dataclass
class ErrorInfo:
    """A call that raised, returned something unusable, or never finished."""

    kind: str  # exception type name, "OutputError", "Timeout", "Crash", "Memory"
    message: str
    where: str = ""  # "line 12 of damping.py: return x"

    def describe(self, call: Optional[Call] = None) -> str:
        from autograder.compare import describe_error

        return describe_error(self, call)


@dataclass
class Outcome:
    """The raw result of one call: named float arrays, or an error."""

    fields: dict = field(default_factory=dict)
    kind: str = ""  # "tuple", "dataclass:DampingState", "dict", "value"
    error: Optional[ErrorInfo] = None


@dataclass
class Context:
    """What a judge sees."""

    check: "Check"
    calls: list
    student: list  # Outcome per call
    reference: list  # Outcome per call
    printed: str = ""  # the first lines the child printed (never parsed)


@dataclass
class Verdict:
    fraction: float
    message: str
    not_implemented: tuple = ()  # TODO names when the stub raised NotImplementedError


@dataclass(frozen=True)
class Check:
    name: str
    exercise: str
    points: float
    calls: Callable[[], list]
    judge: Callable[[Context], Verdict]
    timeout: Optional[float] = None  # seconds; None = the command line's --timeout


def chapters() -> list:
    """The chapter modules, in order (``autograder.checks.chapter1``, ...)."""
    names = sorted(
        (m.name for m in pkgutil.iter_modules(__path__) if m.name.startswith("chapter")),
        key=lambda n: (len(n), n),
    )
    return [importlib.import_module(f"{__name__}.{n}") for n in names]


def all_checks() -> list:
    checks = [check for chapter in chapters() for check in chapter.CHECKS]
    seen = set()
    for check in checks:
        if check.name in seen:
            raise ValueError(f"duplicate check name {check.name!r}")
        seen.add(check.name)
    return checks


def select(checks: list, only) -> list:
    """Checks named by ``only`` (a list of check names, exercise names or prefixes)."""
    if not only:
        return list(checks)
    chosen = []
    for check in checks:
        for name in only:
            if name in (check.name, check.exercise) or check.exercise.startswith(name + ".") or (
                check.name.startswith(name)
            ):
                chosen.append(check)
                break
    return chosen
