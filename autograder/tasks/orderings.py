"""The symbolic elimination's outputs as arrays (``checks/orderings.py``): the separators are a list of
lists of different lengths, which the child cannot return as one array."""

import numpy as np

from autograder.tasks.common import OutputError, encode_lists


def eliminate_task(n, edges, ordering, impl):
    """``orderings.symbolic_elimination(n, edges, ordering)`` as arrays: ``separators`` (encoded by
    ``autograder.tasks.common.encode_lists``), ``parents`` and ``fill`` (an empty fill of any shape as (0, 2))."""
    out = impl.module("orderings").symbolic_elimination(n, edges, ordering)
    if not isinstance(out, (tuple, list)) or len(out) != 3:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (separators, parents, fill)")
    separators, parents, fill = out
    if isinstance(separators, (str, bytes)) or not hasattr(separators, "__len__"):
        raise OutputError(f"separators is {type(separators).__name__}, expected a list of n lists")
    try:
        parents = np.asarray(parents, dtype=float)
        fill = np.asarray(fill, dtype=float)
    except (TypeError, ValueError) as exc:
        raise OutputError(f"parents or fill is not an array of numbers: {exc}") from None
    if fill.size == 0:
        fill = fill.reshape(0, 2)
    return {"separators": encode_lists(separators, "separators"), "parents": parents, "fill": fill}
