"""``bayes_tree.bayes_tree``'s lists of lists as numbers (``checks/bayes_tree.py``): the child returns arrays
only, so each list of lists comes back packed by ``autograder.tasks.common.encode_lists`` and the judge reads
it with ``decode_lists``."""

import numpy as np

from autograder.tasks.common import OutputError, encode_lists


def _ints(value, what):
    """``value`` (a sequence of sequences of ints) as a list of lists of ints, or OutputError."""
    if isinstance(value, (str, bytes, dict)) or not hasattr(value, "__len__"):
        raise OutputError(f"returned {what} of type {type(value).__name__}, expected a list of lists of ints")
    lists = []
    for k, items in enumerate(value):
        try:
            arr = np.asarray(items)
        except Exception as exc:  # noqa: BLE001 - whatever numpy refuses
            raise OutputError(f"returned {what}[{k}] that is not a list of ints: {exc}") from None
        if arr.ndim != 1 and not (arr.ndim == 0 and arr.size == 0):
            raise OutputError(f"returned {what}[{k}] of shape {arr.shape}, expected a flat list of ints")
        if arr.size and (arr.dtype.kind not in "iuf" or not np.all(np.isfinite(arr))
                         or not np.all(arr == np.round(arr))):
            raise OutputError(f"returned {what}[{k}] = {arr.tolist()!r:.60}, expected ints")
        lists.append([int(x) for x in arr.ravel()])
    return lists


def bayes_tree_task(ordering, separators, impl):
    """``bayes_tree.bayes_tree(ordering, separators)``. Fields: ``frontals`` and ``separators`` packed
    (``encode_lists``), ``parents`` (number of cliques,)."""
    out = impl.module("bayes_tree").bayes_tree(np.array(ordering, dtype=np.int64), [list(S) for S in separators])
    if not isinstance(out, tuple) or len(out) != 3:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (frontals, clique_separators, parents)")
    frontals, clique_separators, parents = out
    parents = np.asarray(parents)
    if parents.ndim != 1 or (parents.size and parents.dtype.kind not in "iuf"):
        raise OutputError(f"returned parents of shape {parents.shape} and dtype {parents.dtype}, expected a 1-D "
                          "array of ints")
    return {"frontals": encode_lists(_ints(frontals, "frontals")),
            "separators": encode_lists(_ints(clique_separators, "clique_separators")),
            "parents": parents.astype(float)}
