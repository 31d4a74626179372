"""Bundle adjustment through ``scipy.optimize.least_squares``: scipy's large-scale BA recipe.

The recipe (scipy's cookbook "Large-scale bundle adjustment in scipy"): the unknown is
``x = concat(cameras.ravel(), points.ravel())`` (9C + 3P,), the residual function the
vectorised BAL projection (``course.problems.bal.dataset.residuals``, raveled to (2K,)), the Jacobian by
finite differences ("2-point") with its sparsity pattern given (``jac_sparsity``: row
``2k + i`` touches the 9 columns of camera ``camera_index[k]`` and the 3 of point
``point_index[k]``), so that scipy perturbs groups of independent columns at once and
keeps J sparse; ``method="trf"`` (which then solves its trust-region subproblems with
LSMR), ``x_scale="jac"`` and the recipe's ``ftol=1e-4``.

Cost convention: scipy's cost is ``0.5 * sum f^2`` with ``f`` our residuals: exactly
our BAL cost, over ALL observations. Observations behind the camera: none is treated
apart; the BAL formula ``p = -P.xy / P.z`` is applied as it stands (a point behind its
camera projects through the centre, with a finite residual unless ``P.z = 0``).

The trace: scipy's ``nfev`` counts the residual evaluations of the method, not those of
the finite differences. To record one per ``nfev``, the Jacobian is passed as a
callable that runs scipy's own finite differences (``scipy.optimize._numdiff
.approx_derivative`` with the column groups of ``group_columns``, as ``least_squares``
does with ``jac_sparsity``) on the unrecorded function, reusing the residuals of the
point it is asked at; so the steps are the recipe's. Record 0 is the start, record k the
k-th trial point with ITS chi2 (for a rejected step too), ``accepted`` when scipy went on
from it (it evaluated the Jacobian there) or returned it, ``seconds`` since the start.
"""

from __future__ import annotations

import time

import numpy as np

from course.backends import registry
from course.backends.bal.common import BALRunResult, check_max_iterations, check_method, unpack
from course.core.trace import IterationRecord
from course.problems.bal.dataset import BALProblem, behind_camera, cost, residuals

METHODS = registry.peer_methods("bal", "scipy")
#: the recipe's tolerances (scipy's defaults but ftol, which is 1e-8 there)
TOLERANCES = {"ftol": 1e-4, "xtol": 1e-8, "gtol": 1e-8}
PEER_COST = "scipy's 0.5 sum f^2 with f our residuals: our BAL cost over all observations"


def jacobian_sparsity(problem: BALProblem):
    """The pattern of J (2K, 9C + 3P) as a ``scipy.sparse`` CSR matrix of ones."""
    from scipy.sparse import csr_matrix

    K, C = problem.num_observations, problem.num_cameras
    rows = np.repeat(np.arange(2 * K), 12)
    cam_cols = 9 * problem.camera_index[:, None] + np.arange(9)  # (K, 9)
    point_cols = 9 * C + 3 * problem.point_index[:, None] + np.arange(3)  # (K, 3)
    cols = np.repeat(np.hstack([cam_cols, point_cols]), 2, axis=0).ravel()  # each observation's 2 rows
    shape = (2 * K, 9 * C + 3 * problem.num_points)
    return csr_matrix((np.ones(len(rows)), (rows, cols)), shape=shape)


class _Recorder:
    """The residual function and the finite-difference Jacobian for ``least_squares``; logs
    every residual evaluation scipy makes itself (not the finite differences')."""

    def __init__(self, problem: BALProblem, sparsity, diff_step=None):
        from scipy.optimize._numdiff import group_columns

        self.problem = problem
        self.sparsity = (sparsity, group_columns(sparsity))  # as least_squares prepares jac_sparsity
        self.diff_step = diff_step
        self.evaluations: list = []  # (x copy, chi2, seconds)
        self.jacobian_points: set = set()
        self.last = (None, None)  # (x bytes, f) of the last recorded evaluation
        self.start = time.perf_counter()

    def raw(self, x):
        cameras, points = unpack(self.problem, x)
        p = self.problem
        return residuals(cameras, points, p.camera_index, p.point_index, p.observations).ravel()

    def fun(self, x):
        f = self.raw(x)
        x = np.array(x, dtype=float)
        self.evaluations.append((x, float(f @ f), time.perf_counter() - self.start))
        self.last = (x.tobytes(), f)
        return f

    def jac(self, x):
        from scipy.optimize._numdiff import approx_derivative

        x = np.asarray(x, dtype=float)
        key = x.tobytes()
        self.jacobian_points.add(key)
        f0 = self.last[1] if self.last[0] == key else None
        return approx_derivative(self.raw, x, method="2-point", rel_step=self.diff_step, f0=f0,
                                 sparsity=self.sparsity)

    def trace(self, solution) -> list:
        """One record per recorded evaluation (0 = the start), see the module docstring."""
        records, kept = [], None
        final = np.asarray(solution, dtype=float).tobytes()
        for k, (x, chi2, seconds) in enumerate(self.evaluations):
            if k == 0:
                records.append(IterationRecord(0, chi2, seconds=seconds))
                kept = x
                continue
            key = x.tobytes()
            accepted = key in self.jacobian_points or key == final
            records.append(IterationRecord(iteration=k, chi2=chi2, step_norm=float(np.linalg.norm(x - kept)),
                                          accepted=accepted, seconds=seconds))
            if accepted:
                kept = x
        return records


def solve(problem: BALProblem, method: str = "trf", max_iterations: int = 100, **options) -> BALRunResult:
    """Bundle-adjust ``problem`` from its own start with ``least_squares`` (the recipe above).

    ``max_iterations``: residual evaluations after the start (``max_nfev = max_iterations + 1``;
    the finite differences' evaluations are not counted, as in scipy). ``**options`` go to
    ``least_squares`` over the recipe's (``ftol``, ``xtol``, ``gtol``, ``x_scale``,
    ``diff_step``, ``tr_options``, ``verbose`` ...).

    Returns a ``BALRunResult(backend="scipy")``: ``initial_chi2`` / ``final_chi2`` our
    ``sum |r|^2`` over all observations (scipy's ``2 * cost``, the same function);
    ``iterations = nfev - 1``; ``seconds`` the ``least_squares`` call (the finite
    differences and the small cost of the recording included); the trace above.
    """
    from scipy.optimize import least_squares

    check_method(method, METHODS, "scipy")
    max_iterations = check_max_iterations(max_iterations)
    kwargs = {**TOLERANCES, "x_scale": "jac", **options}
    recorder = _Recorder(problem, jacobian_sparsity(problem), kwargs.pop("diff_step", None))
    x0 = np.concatenate([problem.cameras.ravel(), problem.points.ravel()]).astype(float)
    initial_chi2 = 2.0 * cost(problem)
    start = time.perf_counter()
    recorder.start = start
    result = least_squares(recorder.fun, x0, jac=lambda x: recorder.jac(x), method=method,
                           max_nfev=max_iterations + 1, **kwargs)
    seconds = time.perf_counter() - start
    x = np.asarray(result.x, dtype=float)
    cameras, points = unpack(problem, x)
    final_cost = cost(problem, cameras, points)
    trace = recorder.trace(x)
    return BALRunResult(
        backend="scipy", method=method, params=x.copy(), initial_chi2=initial_chi2, final_chi2=2.0 * final_cost,
        iterations=int(result.nfev) - 1, seconds=seconds, trace=trace,
        stop_reason=f"status {result.status}: {result.message} (nfev {result.nfev}, njev {result.njev})",
        initial_cost=0.5 * initial_chi2, final_cost=final_cost,
        peer_initial_cost=0.5 * trace[0].chi2, peer_final_cost=float(result.cost),
        peer_costs=[0.5 * r.chi2 for r in trace], peer_cost=PEER_COST,
        behind_camera_start=behind_camera(problem), behind_camera_final=behind_camera(problem, cameras, points),
    )
