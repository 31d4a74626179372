"""The symbolic elimination's outputs as arrays (``checks/orderings.py``): the separators are a list of
lists of different lengths, which the child cannot return as one array."""

import numpy as np

from autograder.tasks.common import OutputError


def encode_separators(separators) -> np.ndarray:
    """A list of lists as one flat array: their number, then each one's length and entries."""
    out = [float(len(separators))]
    for k, separator in enumerate(separators):
        try:
            entries = np.asarray(separator, dtype=float).ravel()
        except (TypeError, ValueError) as exc:
            raise OutputError(f"separators[{k}] is not a list of variables: {exc}") from None
        out.append(float(len(entries)))
        out.extend(entries.tolist())
    return np.array(out, dtype=float)


def decode_separators(flat) -> list:
    """The lists of :func:`encode_separators`' array (entries as ints where they are whole numbers)."""
    flat = np.asarray(flat, dtype=float).tolist()
    lists, at = [], 1
    for _ in range(int(flat[0])):
        size = int(flat[at])
        lists.append([int(x) if float(x).is_integer() else x for x in flat[at + 1:at + 1 + size]])
        at += 1 + size
    return lists


def eliminate_task(n, edges, ordering, impl):
    """``orderings.symbolic_elimination(n, edges, ordering)`` as arrays: ``separators`` (encoded by
    :func:`encode_separators`), ``parents`` and ``fill`` (an empty fill of any shape as (0, 2))."""
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
    return {"separators": encode_separators(separators), "parents": parents, "fill": fill}
