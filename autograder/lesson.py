"""The grader in a lesson's cells: ``check("curve_model")`` grades one exercise where the student works,
``hint("residuals_and_jacobian", 2)`` prints one level of its hints. The notebooks import it
(``from autograder.lesson import check, hint``): the framework (``course/``) does not reach the grader.

``check`` is the autograder's own run (``python -m autograder --only NAME --set public``): every
check in a sandboxed child, judged by the same judge on the public checks, the same table and
feedback. It never imports the student's code into the notebook's kernel.
"""

import os
from dataclasses import dataclass

from autograder import hints as hint_texts
from autograder import point_grid, report
from autograder.grade import run


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
