"""The parallel assembly graded alone, with a stand-in kernel (``checks/parallel_assembly.py``)."""

import threading

import numpy as np

from autograder.tasks.common import OutputError

#: the stand-in kernel waits STAGGER_FLOOR + STAGGER_SECONDS * (1 - first / K) on a chunk whose first
#: observation is ``first`` (when it staggers): earlier chunks finish later
STAGGER_FLOOR, STAGGER_SECONDS = 0.002, 0.03
#: the per-observation blocks a stand-in kernel sums (the reference's, computed in the parent)
BLOCK_NAMES = ("U", "V", "W", "g_cam", "g_point", "chi2")


def stagger_delay(first, num_observations) -> float:
    """Seconds the stand-in kernel waits on a chunk starting at observation ``first``."""
    return STAGGER_FLOOR + STAGGER_SECONDS * (1.0 - first / max(num_observations, 1))


class BlockKernel:
    """The per-chunk assembly given to ``parallel_assembly.normal_equations_parallel`` when graded.

    It returns the sums of per-observation blocks that the reference computed in the parent
    (``blocks``: ``U`` (K, 9, 9), ``V`` (K, 3, 3), ``W`` (K, 9, 3), ``g_cam`` (K, 9),
    ``g_point`` (K, 3), ``chi2`` (K,)), so that the grade does not depend on the student's
    ``bundle_adjustment.normal_equations``. It finds a chunk's observations by their rows of
    ``r`` (unique in the grader's inputs), raises a ValueError that says what is wrong when the
    arrays of one call are not the same observations or a chunk is empty, and records the
    observations it was given (``seen``), the threads it ran on and the most calls running at
    once. With ``stagger`` it waits longer on earlier chunks (:func:`stagger_delay`), so that
    the chunks finish in another order than they were submitted and overlap in time.
    """

    def __init__(self, r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                 stagger=False):
        self.r = np.asarray(r, dtype=float)
        self.J_cam, self.J_point = np.asarray(J_cam, dtype=float), np.asarray(J_point, dtype=float)
        self.camera_index, self.point_index = np.asarray(camera_index), np.asarray(point_index)
        self.num_cameras, self.num_points = int(num_cameras), int(num_points)
        self.blocks = {name: np.asarray(blocks[name], dtype=float) for name in BLOCK_NAMES}
        self.stagger = bool(stagger)
        self.rows = {row.tobytes(): k for k, row in enumerate(self.r)}
        if len(self.rows) != len(self.r):
            raise ValueError("BlockKernel: the rows of r must be unique (the grader's inputs are)")
        self.lock = threading.Lock()
        self.seen = np.zeros(len(self.r), dtype=np.int64)
        self.calls = 0
        self.threads = set()
        self.running = 0
        self.most_at_once = 0

    def _rows_of(self, r):
        r = np.asarray(r, dtype=float)
        if r.ndim != 2 or r.shape[1] != 2:
            raise ValueError(f"kernel was called with r of shape {r.shape}, expected a chunk r[lo:hi] of shape (n, 2)")
        if len(r) == 0:
            raise ValueError("kernel was called with an empty chunk (0 observations): make every chunk non-empty "
                             "(with more chunks than observations, one observation per chunk)")
        rows = [self.rows.get(row.tobytes()) for row in r]
        if any(k is None for k in rows):
            raise ValueError("kernel was called with rows that are not rows of r: pass r[lo:hi] as it is")
        return np.array(rows, dtype=np.int64)

    def __call__(self, r, J_cam, J_point, camera_index, point_index, num_cameras, num_points):
        import time

        rows = self._rows_of(r)
        for name, given, full in (("J_cam", J_cam, self.J_cam), ("J_point", J_point, self.J_point),
                                  ("camera_index", camera_index, self.camera_index),
                                  ("point_index", point_index, self.point_index)):
            if not np.array_equal(np.asarray(given), full[rows]):
                raise ValueError(f"kernel was called with {name} of other observations than its r: slice r, "
                                 "J_cam, J_point, camera_index and point_index with the same chunk [lo:hi]")
        if (num_cameras, num_points) != (self.num_cameras, self.num_points):
            raise ValueError(f"kernel was called with num_cameras, num_points = {num_cameras!r}, {num_points!r}, "
                             f"expected {self.num_cameras}, {self.num_points} (every chunk has all cameras and points)")
        with self.lock:
            self.calls += 1
            self.running += 1
            self.most_at_once = max(self.most_at_once, self.running)
            self.threads.add(threading.get_ident())
            np.add.at(self.seen, rows, 1)
        try:
            if self.stagger:
                time.sleep(stagger_delay(int(rows.min()), len(self.r)))
            b = self.blocks
            U, V = np.zeros((self.num_cameras, 9, 9)), np.zeros((self.num_points, 3, 3))
            g_cam, g_point = np.zeros((self.num_cameras, 9)), np.zeros((self.num_points, 3))
            for total, name, index in ((U, "U", self.camera_index), (V, "V", self.point_index),
                                       (g_cam, "g_cam", self.camera_index), (g_point, "g_point", self.point_index)):
                np.add.at(total, index[rows], b[name][rows])
            return U, V, b["W"][rows].copy(), g_cam, g_point, float(np.sum(b["chi2"][rows]))
        finally:
            with self.lock:
                self.running -= 1


def parallel_normal_equations(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                              impl, workers=2, chunks=None, stagger=True):
    """``parallel_assembly.normal_equations_parallel`` with a :class:`BlockKernel` as ``kernel``.

    Returns its six outputs (``U``, ``V``, ``W``, ``g_cam``, ``g_point``, ``chi2``) and what the
    kernel saw: ``calls``, ``threads`` (distinct threads), ``most_at_once`` (kernel calls
    running at the same time), ``missing`` (observations never passed), ``repeated`` (passes
    beyond the first), ``first_missing`` and ``first_repeated`` (-1: none).
    """
    kernel = BlockKernel(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                         stagger=stagger)
    function = impl.module("parallel_assembly").normal_equations_parallel
    out = function(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, workers=workers,
                   chunks=chunks, kernel=kernel)
    if not isinstance(out, tuple) or len(out) != 6:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (U, V, W, g_cam, g_point, chi2)")
    if kernel.calls == 0 and len(kernel.r):
        raise OutputError("never called its kernel argument: assemble every chunk with kernel(r[lo:hi], "
                          "J_cam[lo:hi], ...), which is bundle_adjustment.normal_equations unless given")
    seen = kernel.seen
    missing, repeated = np.flatnonzero(seen == 0), np.flatnonzero(seen > 1)
    return {**dict(zip(BLOCK_NAMES, out)), "calls": float(kernel.calls), "threads": float(len(kernel.threads)),
            "most_at_once": float(kernel.most_at_once), "missing": float(len(missing)),
            "repeated": float(np.sum(seen[repeated] - 1)),
            "first_missing": float(missing[0]) if len(missing) else -1.0,
            "first_repeated": float(repeated[0]) if len(repeated) else -1.0}
