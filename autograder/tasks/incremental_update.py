"""The incremental update's lists as numbers (``checks/incremental_update.py``): the child returns arrays
only, so the sorted lists of variables and cliques come back as int arrays, and ``wildfire_update``'s steps
as one flat array, with a flag saying whether the caller's ``delta`` came back untouched."""

import numpy as np

from autograder.tasks.common import OutputError


def _ints(value, what) -> np.ndarray:
    """``value`` (a flat sequence of whole numbers) as a float array, or OutputError naming ``what``."""
    if isinstance(value, (str, bytes, dict, set)) or not hasattr(value, "__len__"):
        raise OutputError(f"returned {what} of type {type(value).__name__}, expected a sorted list of ints")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise OutputError(f"returned {what} that is not a list of ints: {exc}") from None
    if arr.ndim != 1 and arr.size:
        raise OutputError(f"returned {what} of shape {arr.shape}, expected a flat list of ints")
    if arr.size and (not np.all(np.isfinite(arr)) or not np.all(arr == np.round(arr))):
        raise OutputError(f"returned {what} = {arr.tolist()!r:.60}, expected ints")
    return arr.ravel()


def relinearised(delta, threshold, impl):
    """``relinearised_keys(delta, threshold)``. Field ``keys``."""
    keys = impl.module("incremental_update").relinearised_keys([np.array(s, dtype=float) for s in delta],
                                                                 float(threshold))
    return {"keys": _ints(keys, "the relinearised keys")}


def affected(frontals, clique_separators, parents, new_keys, relinearised, impl):
    """``affected_cliques(...)``. Fields ``top`` and ``orphans``."""
    out = impl.module("incremental_update").affected_cliques(
        [list(F) for F in frontals], [list(S) for S in clique_separators], np.array(parents, dtype=np.int64),
        list(new_keys), list(relinearised))
    if not isinstance(out, tuple) or len(out) != 2:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (top, orphans)")
    return {"top": _ints(out[0], "top"), "orphans": _ints(out[1], "orphans")}


def wildfire(frontals, clique_separators, parents, conditionals, delta, replaced, threshold, impl):
    """``wildfire_update(...)`` on fresh copies of the steps. Fields ``delta`` (the new steps, one variable
    after another), ``recomputed``, and ``kept``: 1 when the ``delta`` given is unchanged after the call
    (the same arrays, holding the same values), 0 when the call wrote into it."""
    given = [np.array(s, dtype=float) for s in delta]
    before = list(given)
    values = [s.copy() for s in given]
    out = impl.module("incremental_update").wildfire_update(
        [list(F) for F in frontals], [list(S) for S in clique_separators], np.array(parents, dtype=np.int64),
        [tuple(np.array(block, dtype=float) for block in triple) for triple in conditionals], given,
        list(replaced), float(threshold))
    kept = (len(given) == len(before) and all(a is b for a, b in zip(given, before))
            and all(np.array_equal(a, b) for a, b in zip(given, values)))
    if not isinstance(out, tuple) or len(out) != 2:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (new_delta, recomputed)")
    steps, recomputed = out
    if isinstance(steps, np.ndarray) or not hasattr(steps, "__len__") or len(steps) != len(values):
        raise OutputError(f"returned new_delta of type {type(steps).__name__}, expected a list of {len(values)} "
                          "arrays, one per variable")
    flat = []
    for v, (step, old) in enumerate(zip(steps, values)):
        try:
            step = np.asarray(step, dtype=float)
        except (TypeError, ValueError) as exc:
            raise OutputError(f"returned new_delta[{v}] that is not an array of numbers: {exc}") from None
        if step.shape != old.shape:
            raise OutputError(f"returned new_delta[{v}] of shape {step.shape}, expected {old.shape} (variable {v}'s "
                              "size)")
        flat.append(step)
    return {"delta": np.concatenate(flat) if flat else np.zeros(0), "recomputed": _ints(recomputed, "recomputed"),
            "kept": float(kept)}
