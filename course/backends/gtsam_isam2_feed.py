"""GTSAM's ISAM2 fed a pose graph one pose at a time: the loop the 2D and 3D drivers share
(``course.backends.posegraph.gtsam_isam2``, ``course.backends.posegraph3d.gtsam_isam2``).

Step k adds pose k with the factors whose later pose is k (step 0 also a prior on pose 0), its initial
value the odometry edge between k - 1 and k (either way round) composed onto ISAM2's current estimate
of pose k - 1 (the file's value where there is no such edge). ``ISAM2Params``: ``relinearizeThreshold``
and ``relinearizeSkip = 1``, the rest GTSAM's defaults. Only ``isam.update`` is timed.
"""

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


class IsamFailed(RuntimeError):
    """GTSAM's ``ISAM2.update`` threw at a step (the message names it)."""


@dataclass
class PoseFamily:
    """What differs between the families, as callables on GTSAM objects: ``initial(k)`` the file's pose k,
    ``prior(pose)`` the prior factor on key 0, ``measurement(e)`` edge e's relative pose, ``between(e, z)``
    its factor, ``estimate(isam, k)`` ISAM2's current pose k."""

    initial: Callable
    prior: Callable
    measurement: Callable
    between: Callable
    estimate: Callable


def feed(edges_i, edges_j, num_poses: int, family: PoseFamily, relinearize_threshold: float) -> tuple:
    """``(isam, {"seconds": (N,) per update, "relinearized": (N,), "reeliminated": (N,)})``. Raises
    ``IsamFailed`` naming the step where ``isam.update`` threw (GTSAM's indeterminate-system error, say)."""
    import gtsam

    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(relinearize_threshold)
    params.relinearizeSkip = 1
    isam = gtsam.ISAM2(params)
    n = int(num_poses)
    edges_i, edges_j = np.asarray(edges_i), np.asarray(edges_j)
    later = np.maximum(edges_i, edges_j)
    arriving = np.argsort(later, kind="stable")
    bounds = np.searchsorted(later[arriving], np.arange(n + 1))
    seconds, relinearized, reeliminated = np.zeros(n), np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    for k in range(n):
        factors = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        initial = family.initial(k)
        if k == 0:
            factors.add(family.prior(initial))
        for e in arriving[bounds[k]:bounds[k + 1]].tolist():
            i, j = int(edges_i[e]), int(edges_j[e])
            z = family.measurement(e)
            factors.add(family.between(e, z))
            if (i, j) == (k - 1, k) and k > 0:
                initial = family.estimate(isam, k - 1).compose(z)
            elif (i, j) == (k, k - 1) and k > 0:  # the odometry from k to k - 1 (intel's order)
                initial = family.estimate(isam, k - 1).compose(z.inverse())
        values.insert(k, initial)
        start = time.perf_counter()
        try:
            result = isam.update(factors, values)
        except RuntimeError as exc:
            first = str(exc).strip().split("\n\n")[0]  # GTSAM's first paragraph, on one line
            first = " ".join(first.split()) or type(exc).__name__
            raise IsamFailed(f"ISAM2's update failed at step {k} of {n}: {first}") from None
        seconds[k] = time.perf_counter() - start
        relinearized[k] = result.getVariablesRelinearized()
        reeliminated[k] = result.getVariablesReeliminated()
    return isam, {"seconds": seconds, "relinearized": relinearized, "reeliminated": reeliminated}
