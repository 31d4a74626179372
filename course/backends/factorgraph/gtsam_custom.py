"""A factor graph through GTSAM's optimizer, each factor a ``gtsam.CustomFactor``: the ``gtsam-custom`` back end.

The error of every factor is OUR residual (``course.factorgraph.factors``, the factor type's own), and
its Jacobians come from our Jets, factor by factor: each call of GTSAM's Python callback evaluates
``autodiff_factor.tangent_jacobians`` of the implementation (with its ``jets.Jet``, each variable seeded
with its kind's ``plus_jacobian``) on that one factor.
That is what a Python custom factor costs: one callback per factor and linearisation, against our
linearisation that evaluates a whole group of factors at once.

The variables are those GTSAM retracts as we do, to first order (the order that the Jacobians see):

- ``Vector``, ``SE2`` and the BAL camera: GTSAM vector values (``Values.insert(key, np.array)``), whose
  retraction is plain addition, chapter 2's convention (an SE(2) angle is wrapped only when the
  solution is read back: our residual wraps the angle difference, so the error does not see it);
- ``SE3``: ``gtsam.Pose3``, whose tangent order is (rotation, translation): GTSAM's retraction is
  ``(R Retract(omega), t + R v)`` to first order, ours ``(R Exp(phi), t + R rho)`` with ``(rho, phi)``,
  so GTSAM's Jacobian is ours with its column blocks swapped (``POSE3_COLUMNS``). Beyond first order the
  two retractions differ (GTSAM's Rot3 retraction is the Cayley map or Exp, as its build chose): the
  iterates differ, not the minimum;
- ``SO3``: ``gtsam.Rot3`` (tangent as ours).

Fixed variables are not variables for GTSAM (as ``course.backends.posegraph.gtsam`` does): a factor
holds a fixed variable's value as a constant and has keys for its free ones only; a factor of fixed
variables alone is a constant of the error and is left out (``final_chi2`` counts it: it is our error
on the solution, ``FactorGraphProblem.chi2``). The noise model is ``noiseModel.Gaussian.Information`` of
the factor's information, so that GTSAM's error is exactly half our chi2 (plus those constants).

A group's robust loss is GTSAM's ``noiseModel.Robust`` of the same kernel (:func:`robust_estimator`;
GTSAM reweights, ours adds the curvature term: the iterates differ, not the minimum). A partly fixed
variable (``graph.fix(key, dofs)``) is a GTSAM variable whose Jacobians have the held dofs' columns
zeroed: Levenberg-Marquardt's damping then gives them a zero step (exactly held for vectors and
SE(2); a ``Pose3``'s retraction mixes rotation into translation beyond first order, so there the
held dofs drift at second order of the others' steps).
"""

import time

import numpy as np

from course.core import impl as impl_loader
from course.core.backend_names import GTSAM_CUSTOM
from course.core.trace import IterationRecord, RunResult

METHODS = ("levenberg-marquardt",)
#: GTSAM's Pose3 tangent (omega, v) from ours (rho, phi): the columns of our Jacobian, in GTSAM's order
POSE3_COLUMNS = np.array([3, 4, 5, 0, 1, 2])


def _kind_io(kind):
    """``(to_gtsam(value), read(values, key) -> (1, *shape), columns or None)`` for a variable kind."""
    import gtsam

    from course.factorgraph.variables import se3_value

    if kind.name == "SE3":
        def to_gtsam(value):
            return gtsam.Pose3(gtsam.Rot3(value[3:].reshape(3, 3)), value[:3])

        def read(values, key):
            pose = values.atPose3(key)
            return se3_value(pose.translation(), pose.rotation().matrix())[None]

        return to_gtsam, read, POSE3_COLUMNS
    if kind.name == "SO3":
        return (lambda value: gtsam.Rot3(value)), (lambda values, key: values.atRot3(key).matrix()[None]), None
    if kind.name in ("SE2", "BALCamera") or kind.name.startswith("Vector"):
        return (lambda value: np.array(value, dtype=float)), \
            (lambda values, key: np.asarray(values.atVector(key), dtype=float)[None]), None
    raise ValueError(f"gtsam-custom: no GTSAM value for variables of kind {kind.name}")


def _error_function(ftype, z, constants, free, tangent_jacobians, jet, held=None):
    """The callback of one factor: ``constants`` (per slot, the fixed value (1, *shape) or None),
    ``free`` ``[(slot, key, read, columns)]`` in the order of the factor's keys; ``held`` (per entry of
    ``free``, the tangent indices held of a partly fixed variable, or ()) zeroes those Jacobian columns."""
    held = held or [()] * len(free)
    kinds = ftype.kinds

    def residual(*points):
        full = list(constants)
        for (slot, _, _, _), point in zip(free, points):
            full[slot] = point
        return ftype.residual(z, *full)

    def error(this, values, H):
        points = [read(values, key) for _, key, read, _ in free]
        if H is None:  # the error alone: plain arrays
            return np.asarray(residual(*points), dtype=float)[0]
        plus = [kinds[slot].plus_jacobian(point) for (slot, _, _, _), point in zip(free, points)]
        r, J = tangent_jacobians(residual, plus, points, jet)
        for a, ((_, _, _, columns), block, dofs) in enumerate(zip(free, J, held)):
            block = np.array(block, dtype=float)[0]
            block[:, list(dofs)] = 0.0  # a partly fixed variable: its held dofs do not move
            H[a] = block if columns is None else block[:, columns]
        return np.asarray(r, dtype=float)[0]

    return error


def robust_estimator(loss):
    """GTSAM's M-estimator of a robust loss: chapter 4's Huber, Cauchy and Tukey kernels on ``s = |r|^2``
    are twice GTSAM's on ``e = |r|`` with ``k = a`` (Huber ``2 a e - a^2`` against ``k e - k^2 / 2``), so
    that GTSAM's error stays half our chi2."""
    import gtsam

    make = {"huber": gtsam.noiseModel.mEstimator.Huber, "cauchy": gtsam.noiseModel.mEstimator.Cauchy,
            "tukey": gtsam.noiseModel.mEstimator.Tukey}[loss.kernel]
    return make.Create(float(loss.scale))


def build(graph, impl="solutions"):
    """``(factors, values, free, constant_chi2)`` for the factor graph ``graph`` at its values.

    GTSAM's keys are our variable indices; ``free`` lists the variables in ``values``;
    ``constant_chi2`` is the chi2 of the factors on fixed variables alone (left out)."""
    import gtsam

    loaded = impl_loader.load(impl)
    jet = loaded.module("jets").Jet
    tangent_jacobians = loaded.module("autodiff_factor").tangent_jacobians
    fixed = set(int(v) for v in graph.fixed)
    io = {kind: _kind_io(kind) for kind in dict.fromkeys(graph.kinds)}
    values = gtsam.Values()
    free = [v for v in range(graph.num_variables) if v not in fixed]
    for v in free:
        values.insert(v, io[graph.kinds[v]][0](graph.values[v]))
    factors = gtsam.NonlinearFactorGraph()
    constant_chi2 = 0.0
    for group in graph.groups.values():
        ftype = group.type
        keys, z, info = group.arrays()
        for m in range(len(keys)):
            variables = [int(v) for v in keys[m]]
            constants = [graph.values[v][None] if v in fixed else None for v in variables]
            mine = [(slot, v, io[graph.kinds[v]][1], io[graph.kinds[v]][2])
                    for slot, v in enumerate(variables) if v not in fixed]
            if not mine:
                r = np.asarray(ftype.residual(z[m:m + 1], *constants), dtype=float)[0]
                constant_chi2 += float(r @ (r if info is None else info[m] @ r))
                continue
            model = gtsam.noiseModel.Unit.Create(ftype.dim) if info is None else \
                gtsam.noiseModel.Gaussian.Information(np.array(info[m]))
            if group.loss is not None:
                model = gtsam.noiseModel.Robust.Create(robust_estimator(group.loss), model)
            held = [graph.fixed_dofs.get(v, ()) for _, v, _, _ in mine]
            error = _error_function(ftype, z[m:m + 1], constants, mine, tangent_jacobians, jet, held)
            factors.add(gtsam.CustomFactor(model, [v for _, v, _, _ in mine], error))
    return factors, values, free, constant_chi2


def read_values(graph, gtsam_values, free) -> list:
    """The variables' values at ``gtsam_values`` (the fixed ones as held), as our kinds store them
    (an SE(2) angle wrapped by the retraction)."""
    out = [np.array(v, dtype=float) for v in graph.values]
    for v in free:
        kind = graph.kinds[v]
        value = _kind_io(kind)[1](gtsam_values, v)
        out[v] = np.asarray(kind.retract(value, np.zeros((1, kind.dim))), dtype=float)[0]
    return out


def solve(graph, method: str = "levenberg-marquardt", max_iterations: int = 100, *, impl="solutions",
          relative_error_tol: float = 1e-12, absolute_error_tol: float = 1e-12) -> RunResult:
    """Optimize the factor graph ``graph`` (``course.factorgraph.FactorGraph``) from its values with
    GTSAM's ``LevenbergMarquardtOptimizer`` on custom factors (see the module doc).

    Returns a ``RunResult``: ``params`` every variable's stored value, one after the other (as
    ``FactorGraphProblem``'s ``x``); ``final_chi2`` our error there; ``iterations`` GTSAM's;
    ``seconds`` its ``optimize()`` alone; the trace's chi2 twice GTSAM's error after each iteration
    (plus the constant factors'), which is our chi2 since the error is ours.
    """
    import gtsam

    from course.factorgraph import FactorGraphProblem

    if method not in METHODS:
        raise ValueError(f"unknown gtsam-custom method {method!r}; choose one of {METHODS}")
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    ours = FactorGraphProblem(graph, impl)
    initial_chi2 = ours.chi2(ours.x0)
    factors, values, free, constant_chi2 = build(graph, impl)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(int(max_iterations))
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(absolute_error_tol)
    trace = [IterationRecord(0, initial_chi2)]
    errors: list = []
    optimizer = None
    start = time.perf_counter()

    def hook(iteration, error_before, error_after):
        errors.append((error_before, error_after))
        if iteration > trace[-1].iteration:
            trace.append(IterationRecord(int(iteration), 2.0 * error_after + constant_chi2,
                                         damping=float(optimizer.lambda_()) if optimizer is not None else np.nan,
                                         accepted=error_after <= error_before,
                                         seconds=time.perf_counter() - start))

    params.iterationHook = hook
    optimizer = gtsam.LevenbergMarquardtOptimizer(factors, values, params)
    start = time.perf_counter()
    failure = None
    try:
        optimizer.optimize()
    except NotImplementedError:  # a TODO of the implementation's Jets, raised in a callback: not GTSAM's failure
        raise
    except RuntimeError as exc:
        failure = " ".join(str(exc).split())
    seconds = time.perf_counter() - start
    iterations = int(optimizer.iterations())
    final = ours.x0.copy() if iterations == 0 else \
        np.concatenate([v.ravel() for v in read_values(graph, optimizer.values(), free)])
    if failure is not None:
        stop = f"failed: {failure}"
    elif iterations >= max_iterations:
        stop = f"max_iterations: {max_iterations} reached"
    elif optimizer.lambda_() >= params.getlambdaUpperBound():
        stop = f"lambda_upper_bound: no decreasing step with lambda up to {params.getlambdaUpperBound():g}"
    else:
        stop = f"converged: error decrease <= {relative_error_tol:g} relative and <= {absolute_error_tol:g} absolute"
    return RunResult(backend=GTSAM_CUSTOM, method=method, params=final, initial_chi2=initial_chi2,
                     final_chi2=ours.chi2(final), iterations=iterations, seconds=seconds, trace=trace,
                     stop_reason=stop)
