"""What a lesson's cells call beside the experiments: ``check("curve_model")`` grades one exercise
where the student works, ``hint("residuals_and_jacobian", 2)`` prints one level of its hints.

``check`` is the autograder's own run (``python -m autograder --only NAME --set public``): every
check in a sandboxed child, judged by the same judge on the public checks, the same table and
feedback. It never imports the student's code into the notebook's kernel.
"""

import contextlib
import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import NamedTuple

from autograder import hints as hint_texts
from autograder import point_grid, report
from autograder.grade import run
from course.core import impl as impl_loader
from course.core.impl import not_implemented_reason


@dataclass
class CheckSummary:
    """One exercise's public score; its ``repr`` is the one line a cell shows under the table."""

    exercise: str
    impl: str
    score: float
    max_score: float
    not_implemented: int

    @property
    def full(self) -> bool:
        return self.max_score > 0 and self.score >= self.max_score - 1e-9

    def __repr__(self) -> str:
        if self.full:
            state = "full marks on the public checks"
        elif self.not_implemented:
            state = f"{self.not_implemented} check(s) reach a TODO: write the function, then run this cell again"
        else:
            state = "see the details above"
        return (f"{self.exercise} ({self.impl}): {report.points(self.score)} / "
                f"{report.points(self.max_score)} points, {state}")


def default_impl() -> str:
    """The notebook's implementation: ``COURSE_IMPL`` when set (``notebooks.build --impl``), else your
    ``exercises``."""
    return os.environ.get("COURSE_IMPL") or "exercises"


def check(exercise: str, impl: str | None = None, timeout: float | None = None, workers: int = 2) -> CheckSummary:
    """Grade ``exercise`` (an exercise's name, or one check's) on the public checks; print the
    autograder's table and feedback; return the score (:class:`CheckSummary`)."""
    impl = impl or default_impl()
    notices: list = []
    options = {"timeout": timeout} if timeout is not None else {}
    from autograder.checks import SelectionError

    try:
        results, seconds = run(impl, [exercise], which="public", workers=workers, notices=notices, **options)
    except SelectionError as exc:
        raise ValueError(f"check({exercise!r}): no check or exercise of that name ({exc})") from None
    if not results:
        raise ValueError(f"check({exercise!r}): no check or exercise of that name")
    for line in notices:
        print(f"autograder: {line}")
    print(report.table(results, impl, seconds, workers, "public"))
    return CheckSummary(exercise, impl, point_grid.total(r.score for r in results),
                        point_grid.total(r.max_score for r in results),
                        sum(1 for r in results if r.not_implemented))


def hint(name: str, level: int = 1) -> None:
    """Print level ``level`` (1 the approach, 2 the key identity, 3 the result) of ``name``'s hints."""
    print(hint_texts.text(name, level))


@contextlib.contextmanager
def todo_as_one_line(out=print) -> Iterator[None]:
    """Run the ``with`` block; an unwritten exercise (``NotImplementedError``) ends it with one line
    naming the TODO, a peer library that is not installed (``ImportError``) with one line naming it:
    a lesson's cell that calls the student's code never stops the notebook with a traceback."""
    try:
        yield
    except NotImplementedError as exc:
        out(f"{not_implemented_reason(exc)}: write it, then run this cell again")
    except ImportError as exc:
        out(f"not run here: {exc.name or exc} is not installed (the peers extra)")


def exercise(name: str, impl="solutions"):
    """The module ``name`` of implementation ``impl`` (``"solutions"``, ``"exercises"`` or a path)."""
    return impl_loader.load(impl).module(name)


class JacobianSetup(NamedTuple):
    """The arguments of one ``course.check_jacobian(f, x, J=J, plus=plus, names=names, rows=rows)``: the
    function, the point (one array per variable), the Jacobian blocks to check, each variable's space,
    the blocks' names and the residual's rows."""

    f: Callable
    x: list
    J: list
    plus: list
    names: list
    rows: list
