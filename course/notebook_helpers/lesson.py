"""What a lesson's cells call around the student's code: ``todo_as_one_line`` (an unwritten TODO is one
line, not a traceback), ``exercise`` (a module of an implementation) and ``JacobianSetup`` (the arguments of
one ``course.check_jacobian``). The lessons' ``check`` and ``hint`` cells are the grader's
(:mod:`autograder.lesson`), which the notebooks import themselves.
"""

import contextlib
from collections.abc import Callable, Iterator
from typing import NamedTuple

from course.core import impl as impl_loader
from course.core.impl import not_implemented_reason


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
