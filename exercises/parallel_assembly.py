"""Chapter 4 exercise: the block normal equations of bundle adjustment, assembled in parallel.

The assembly of ``bundle_adjustment.normal_equations`` is a sum over observations: split the
K observations into contiguous chunks, assemble each chunk's partial blocks on its own
thread, and add the partial sums. With chunks ``[b_0, b_1), [b_1, b_2), ..., [b_{n-1}, b_n)``
(``b_0 = 0``, ``b_n = K``) and ``U^(i), V^(i), g^(i), chi2^(i)`` the sums over chunk i::

    U = sum_i U^(i)   (C, 9, 9)      V = sum_i V^(i)   (P, 3, 3)
    g_cam = sum_i g_cam^(i)  (C, 9)  g_point = sum_i g_point^(i)  (P, 3)  chi2 = sum_i chi2^(i)
    W = [W^(0); W^(1); ...; W^(n-1)]   (K, 9, 3): one block per observation, in observation order

(U^(i)_c = sum of J_cam_k^T J_cam_k over the observations k of chunk i seen by camera c,
and so on: see ``bundle_adjustment.normal_equations``.) Floating-point addition is not
associative, so the result equals the serial assembly to rounding (about 1e-15 relative),
not bit for bit, and depends on the chunking.

Why threads (``concurrent.futures.ThreadPoolExecutor``), not processes or numba:

- the per-chunk work is a handful of large numpy calls (batched ``np.matmul``, ``np.bincount``,
  ``np.add.at``, fancy indexing), and numpy releases the GIL inside them once an array holds
  more than a few hundred entries: a pure-Python thread keeps running during ``np.matmul``,
  ``np.einsum``, ``np.add.at`` and fancy indexing, and during about three quarters of an
  ``np.bincount`` (its pass over the indices keeps the GIL), but not during one product of
  2-D arrays, ``A.T @ B`` (``np.dot(A.T, B)`` releases it); ``course.app.parallel_speedup.gil_table``
  measures it. The Python glue between the calls, microseconds per chunk, holds it too;
- threads share the Jacobians: nothing is copied. Processes must pickle each chunk's
  Jacobians to a worker and its blocks back, which on ladybug-49 costs more than the whole
  serial assembly (the ``2p`` row of ``python -m course benchmark``), and every process
  counts against the grader's process and memory limits;
- numba would compile loops of its own (its wheels cover CPython 3.10 to 3.15), but it adds
  numba and llvmlite to what grading installs, and compiles at the first call in every
  fresh process (every autograder check runs in one); the lesson here is about numpy.

Each thread keeps the course's one BLAS thread (``course/core/threads.py``): the parallelism is
over chunks, not inside a product.

When does it pay? Measured by ``python -m course benchmark`` (``course/app/parallel_speedup.py``,
whose docstring explains the figures), on 2 cores shared with other jobs: not on ladybug-49
(31843 observations: two threads 0.85 times the serial speed, four 1.1 times), where the
work is memory-bound and the parallel version pays for the partial sums; 1.5 times with four
chunks on 105k observations when both cores are free; 2 to 4 times slower on a thousand
observations (starting the threads costs more than the work, and numpy keeps the GIL on small
arrays); nothing when another job holds a core. And the assembly is only 15 to 22 % of a
Levenberg-Marquardt or dogleg step attempt (the Schur solve, the Jacobians and the trial chi2
stay serial), so a whole iteration cannot gain more than a few percent.

Inputs at the edges of the contract (each is a check input):
- chunk_bounds: no observations (K = 0: b = [0], no chunk)
- chunk_bounds: one observation (K = 1)
- chunk_bounds: more chunks than observations (one observation per chunk)
- chunk_bounds: as many chunks as observations
- chunk_bounds: one chunk
- normal_equations_parallel: more chunks than observations
- normal_equations_parallel: one worker
- normal_equations_parallel: one observation on two workers (one chunk; a camera and points seen by none)
- normal_equations_parallel: no observations (K = 0: zero blocks, W (0, 9, 3), chi2 0)

Allowed imports: numpy, scipy, concurrent.futures, .bundle_adjustment.
"""

import concurrent.futures
import numbers

import numpy as np

from . import bundle_adjustment


def _count(value, name: str, minimum: int = 1) -> int:
    """``value`` as an int ``>= minimum``; a TypeError or ValueError naming ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer >= {minimum}, got {value!r} ({type(value).__name__})")
    if value < minimum:
        raise ValueError(f"{name} must be an integer >= {minimum}, got {value}")
    return int(value)


def chunk_bounds(num_observations, chunks):
    """Bounds ``b`` (n + 1,) int of ``n = min(chunks, num_observations)`` contiguous chunks.

    Chunk i is the observations ``b[i] <= k < b[i + 1]``: ``b[0] = 0``, ``b[n] = num_observations``,
    every chunk non-empty, and the sizes differ by at most one (balanced work for the threads).
    With K observations and n chunks, the first ``K mod n`` chunks hold ``K // n + 1`` observations
    and the others ``K // n``. More chunks than observations gives one observation per chunk (never
    an empty chunk); no observations gives ``b = [0]`` (no chunk).

    Example: ``chunk_bounds(10, 4)`` is ``[0, 3, 6, 8, 10]`` (sizes 3, 3, 2, 2). Derive ``b[i]`` in
    closed form (``python -m autograder hint chunk_bounds 1``).
    """
    num_observations = _count(num_observations, "num_observations", minimum=0)
    chunks = _count(chunks, "chunks")
    raise NotImplementedError("TODO parallel_assembly.chunk_bounds: not implemented yet")


def normal_equations_parallel(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points,
                              workers=2, chunks=None, kernel=None):
    """``bundle_adjustment.normal_equations``, assembled over chunks of observations on threads.

    Arguments and outputs as ``normal_equations``: r (K, 2), J_cam (K, 2, 9), J_point (K, 2, 3),
    camera_index, point_index (K,) int; returns ``U`` (C, 9, 9), ``V`` (P, 3, 3), ``W`` (K, 9, 3),
    ``g_cam`` (C, 9), ``g_point`` (P, 3), ``chi2`` (float) (module docstring for the sums).

    - ``workers``: threads (``concurrent.futures.ThreadPoolExecutor(max_workers=workers)``);
    - ``chunks``: how many chunks (``chunk_bounds``); None means one per worker;
    - ``kernel``: the serial assembly of one chunk, called as
      ``kernel(r[lo:hi], J_cam[lo:hi], J_point[lo:hi], camera_index[lo:hi], point_index[lo:hi],
      num_cameras, num_points)`` and returning that chunk's ``(U, V, W, g_cam, g_point, chi2)``;
      None means this implementation's ``bundle_adjustment.normal_equations``.

    Submit every chunk before waiting for any (a chunk waited for at once runs alone), then add
    the partial sums here, in the calling thread, and put the chunks' W back in observation
    order: take the results in the order of submission, not of completion
    (``concurrent.futures.as_completed``). Call ``kernel`` only: the grader passes its own to
    grade this function alone, and checks that chunks run at the same time
    (``python -m autograder hint normal_equations_parallel 1``, then 2 and 3).
    """
    workers = _count(workers, "workers")
    chunks = workers if chunks is None else _count(chunks, "chunks")
    if kernel is None:
        kernel = bundle_adjustment.normal_equations
    if not callable(kernel):
        raise TypeError(f"kernel must be a function like bundle_adjustment.normal_equations, got {kernel!r}")
    r, J_cam, J_point = np.asarray(r), np.asarray(J_cam), np.asarray(J_point)
    camera_index, point_index = np.asarray(camera_index), np.asarray(point_index)
    raise NotImplementedError("TODO parallel_assembly.normal_equations_parallel: not implemented yet")
