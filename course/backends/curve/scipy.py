"""The chapter 1 curve fit through ``scipy.optimize.least_squares`` (a peer).

``y = exp(a x^2 + b x + c)``: scipy minimizes ``1/2 sum f_k^2`` with the whitened
residuals ``f = sqrt(w) r`` (m,) and their Jacobian ``sqrt(w)[:, None] J`` (m, 3), ``r`` and ``J``
the implementation's ``curve_model.residuals_and_jacobian`` (chapter 1's exercise: the peer runs
the student's model, as our solvers do), so ``sum f^2`` is our chi2. Same data, same start
(``data.start``) and same weights as our solvers.

Methods: ``lm`` (MINPACK's ``lmder``: Levenberg-Marquardt with Moré's trust region)
and ``trf`` (trust-region reflective; unbounded here, so a plain trust-region method
with Coleman-Li scaling).

What the trace holds, honestly: scipy has no per-iteration callback for ``lm`` (the
``callback`` argument, new in scipy 1.16, is implemented for ``trf`` and ``dogbox``
only). So, for both methods alike, the residual function is wrapped and records
``chi2 = f^T f`` at every residual evaluation. With an analytic Jacobian both methods
evaluate the residuals once at the start and once per trial point, so the trace is one
record per *step attempt*, as in our own loop: record 0 is the start, record k the
k-th trial point with the chi2 *of that trial point* (for a rejected step too).
A trial point is marked ``accepted`` when the method went on from it, i.e. when the
Jacobian was later evaluated at exactly that point (both methods evaluate the Jacobian
after every accepted step and only then), or when it is the returned solution.
``damping``, ``rho`` are NaN (scipy does not expose lambda or the trust radius),
``step_norm`` is the distance from the point kept before the attempt, ``seconds`` the
time since the solve started.

``iterations = nfev - 1``: residual evaluations minus the one at the start, i.e.
the step attempts (accepted or not), the same count as ours and Ceres'. ``njev``
(Jacobian evaluations, about the accepted steps) goes into ``stop_reason``.
``seconds`` is the ``least_squares`` call alone, including the small cost of the
recording wrapper (one dot product per evaluation).
"""

import time

import numpy as np

from course.backends import registry
from course.core import impl as impl_loader
from course.core.errors import NonFiniteError
from course.core.trace import IterationRecord, RunResult
from course.problems.curve.problem import curve_chi2

METHODS = registry.peer_methods("curve", "scipy")

#: tolerances passed to least_squares unless overridden: far below scipy's 1e-8 so that
#: the minimum agrees with ours to 1e-6 relative (MINPACK needs them above machine eps).
TOLERANCES = {"ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15}


class _Recorder:
    """Residual and Jacobian functions for least_squares that log every call; ``model`` is the
    implementation's ``residuals_and_jacobian(params, x, y) -> (r (m,), J (m, 3))``, called once per
    point (the Jacobian of the last residual evaluation is kept)."""

    def __init__(self, data, model):
        self.x, self.y = np.asarray(data.x, float), np.asarray(data.y, float)
        self.sqrt_w = np.sqrt(np.asarray(data.weights, float))
        self.model = model
        self.evaluations = []  # (params copy, chi2, seconds)
        self.jacobian_points = set()
        self.last: tuple | None = None  # (params bytes, J whitened)
        self.start = time.perf_counter()

    def _evaluate(self, p):
        p = np.array(p, dtype=float)
        with np.errstate(over="ignore", invalid="ignore"):
            r, J = self.model(p.copy(), self.x.copy(), self.y.copy())
        f = self.sqrt_w * np.asarray(r, dtype=float)
        self.last = (p.tobytes(), self.sqrt_w[:, None] * np.asarray(J, dtype=float))
        return p, f

    def residuals(self, p):
        p, f = self._evaluate(p)
        self.evaluations.append((p, float(f @ f), time.perf_counter() - self.start))
        return f

    def jacobian(self, p):
        key = np.asarray(p, dtype=float).tobytes()
        self.jacobian_points.add(key)
        if self.last is None or self.last[0] != key:
            self._evaluate(p)
        assert self.last is not None
        return self.last[1]

    def trace(self, solution):
        """One record per residual evaluation (0 = the start), see the module docstring."""
        records, kept = [], None
        final = np.asarray(solution, dtype=float).tobytes()
        for k, (p, chi2, seconds) in enumerate(self.evaluations):
            if k == 0:
                records.append(IterationRecord(0, chi2, seconds=seconds))
                kept = p
                continue
            key = p.tobytes()
            accepted = key in self.jacobian_points or key == final
            records.append(
                IterationRecord(
                    iteration=k,
                    chi2=chi2,
                    step_norm=float(np.linalg.norm(p - kept)),
                    accepted=accepted,
                    seconds=seconds,
                )
            )
            if accepted:
                kept = p
        return records


def solve(data, method="lm", max_iterations=100, impl="solutions", **options) -> RunResult:
    """Fit ``data`` (a ``CurveData``) with ``scipy.optimize.least_squares(method=...)``.

    Args:
        data: ``course.problems.curve.problem.CurveData``; starts from ``data.start``.
        method: ``"lm"`` or ``"trf"``.
        max_iterations: step attempts allowed, passed as ``max_nfev = max_iterations + 1``.
        impl: the implementation whose ``curve_model`` gives the residuals and the Jacobian
            (``NotImplementedError`` naming the TODO while it is one).
        **options: passed to ``least_squares`` (e.g. ``ftol``, ``x_scale``); the
            defaults are ``TOLERANCES``.

    Returns:
        ``RunResult(backend="scipy")``: ``final_chi2`` and ``initial_chi2`` by our error,
        ``iterations = nfev - 1``, the trace described in the module docstring.
    """
    from scipy.optimize import least_squares

    if method not in METHODS:
        raise ValueError(f"scipy: unknown method {method!r}; choose one of {METHODS}")
    start = np.array(data.start, dtype=float)
    initial_chi2 = curve_chi2(data, start)
    if not np.isfinite(initial_chi2):
        raise NonFiniteError(f"scipy_curve: the model is not finite at the start {start.tolist()}")
    kwargs = dict(TOLERANCES)
    kwargs.update(options)
    recorder = _Recorder(data, impl_loader.load(impl).module("curve_model").residuals_and_jacobian)
    recorder.residuals(start)  # a TODO raises here, before scipy; the start is record 0 either way
    recorder.evaluations.clear()
    t0 = time.perf_counter()
    recorder.start = t0
    result = least_squares(
        recorder.residuals,
        start,
        jac=recorder.jacobian,
        method=method,
        max_nfev=max_iterations + 1,
        **kwargs,
    )
    seconds = time.perf_counter() - t0
    params = np.asarray(result.x, dtype=float)
    return RunResult(
        backend="scipy",
        method=method,
        params=params,
        initial_chi2=initial_chi2,
        final_chi2=curve_chi2(data, params),
        iterations=int(result.nfev) - 1,
        seconds=seconds,
        trace=recorder.trace(params),
        stop_reason=f"status {result.status}: {result.message} (nfev {result.nfev}, njev {result.njev})",
    )
