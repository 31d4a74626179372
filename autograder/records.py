"""The records the grader passes around: a call the child makes, its raw outcome, the
judge's context and verdict, and a check. Plain data, shared by the sandbox, the judges
and the report; nothing here runs student code or knows a reference answer.
"""

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Call:
    """One call the child makes: ``target(*args, **kwargs)``.

    ``returns`` says how the raw output is read: a tuple of names for a tuple
    (``("r", "J")``), ``"state"`` for a ``DampingState`` (fields ``lam``, ``nu``),
    ``"value"`` for one array or scalar, ``"dict"`` for a framework task's dict of arrays.
    ``where`` describes the inputs in feedback ("at params (0, 0, 0)"); ``label``
    replaces the target's name in feedback; ``groups`` names kinds of rows of the inputs.
    """

    target: str
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    init: dict = field(default_factory=dict)
    returns: Any = "value"
    where: str = ""
    label: str = ""  # how feedback names the call; default from target
    #: kinds of input among the rows of the call's outputs (their first axis: the edges, the
    #: observations): ``{"whose residual rotation is 2.9 rad": (7,)}``, for feedback to say on which
    #: kind the output goes wrong when it is not all of them
    groups: dict = field(default_factory=dict)

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


@dataclass
class Outcome:
    """The raw result of one call: named float arrays, or an error."""

    fields: dict = field(default_factory=dict)
    kind: str = ""  # "tuple", "dataclass:DampingState", "dict", "value"
    error: ErrorInfo | None = None
    modified: tuple = ()  # names of the arguments the call changed in place


@dataclass
class Context:
    """What a judge sees."""

    check: "Check"
    calls: list
    student: list  # Outcome per call
    reference: list  # Outcome per call
    printed: str = ""  # the first lines the child printed (never parsed)
    #: per call, the outputs of known mistakes on its inputs: ``{key: [(value, why), ...]}``
    mistakes: list = field(default_factory=list)

    def known(self, index: int) -> dict:
        """The known mistakes of call ``index`` (empty when the check names none)."""
        return self.mistakes[index] if index < len(self.mistakes) else {}


@dataclass
class Verdict:
    fraction: float
    message: str
    not_implemented: tuple = ()  # TODO names when the stub raised NotImplementedError


@dataclass(frozen=True)
class Check:
    """One graded behaviour: ``calls(seed)`` builds the calls (``seed=None``: the public
    inputs; an int: fresh hidden ones); ``judge`` turns a :class:`Context` into a Verdict."""

    name: str
    exercise: str
    points: float
    calls: Callable[..., list]
    judge: Callable[[Context], Verdict]
    timeout: float | None = None  # seconds; None = the command line's --timeout
    needs: tuple = ()  # libraries outside the core it imports (e.g. "pyceres"); absent: not run, 0 points
    #: the inputs sit exactly on a value the contract decides (a threshold, exact in binary, met by
    #: arithmetic that no BLAS or LAPACK rounds): moving them by an ulp would change the question
    exact_inputs: bool = False
