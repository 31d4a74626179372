"""The edge cost as Ceres evaluates it (``checks/ceres_edge_cost.py``)."""

import numpy as np

from autograder.tasks.common import OutputError, stub_todo


def _ceres_cost(impl, measurement, sqrt_information):
    cls = impl.module("ceres_edge_cost").SE2EdgeCost
    try:
        return cls(np.array(measurement, dtype=float), np.array(sqrt_information, dtype=float))
    except NotImplementedError as exc:
        import pyceres

        class _Bare(cls):
            def __init__(self):
                pyceres.CostFunction.__init__(self)
                self.set_num_residuals(3)
                self.set_parameter_block_sizes([3, 3])

        todo = stub_todo(lambda: _Bare().Evaluate([np.zeros(3), np.zeros(3)], np.zeros(3), None))
        raise NotImplementedError(f"{exc}; {todo}" if todo else str(exc)) from None


def ceres_cost(measurement, sqrt_information, x_i, x_j, impl):
    """Residuals (3,) and Jacobians (3, 3) of ``SE2EdgeCost`` as Ceres computes them
    (``CostFunction.evaluate``, which calls the student's ``Evaluate``)."""
    cost = _ceres_cost(impl, measurement, sqrt_information)
    residuals, jacobians = cost.evaluate(np.array(x_i, dtype=float), np.array(x_j, dtype=float))
    if residuals is None or jacobians is None:
        raise OutputError("made Ceres' evaluation fail: Evaluate must return True after filling "
                          "residuals and jacobians (it returned False or None)")
    return {"r": np.asarray(residuals).ravel(), "J_i": np.asarray(jacobians[0]),
            "J_j": np.asarray(jacobians[1])}


def ceres_partial_jacobians(measurement, sqrt_information, x_i, x_j, impl):
    """``Evaluate`` called directly with NaN-filled buffers: with both Jacobians requested
    (``both``), for residuals only (``none``: ``jacobians=None``) and for a constant block
    (``first``: ``[None, J_j]``, ``second``: ``[J_i, None]``), as Ceres does.

    Fields per request: ``{req}_r`` (3,), ``{req}_J`` (9,) (the requested Jacobian: J_i
    for ``both``, NaN for ``none``), ``{req}_J2`` (J_j for ``both``) and ``{req}_ok``
    (Evaluate returned True).
    """
    cost = _ceres_cost(impl, measurement, sqrt_information)
    parameters = [np.array(x_i, dtype=float), np.array(x_j, dtype=float)]
    out = {}
    for request in ("both", "none", "first", "second"):
        residuals = np.full(3, np.nan)
        buffers = {"both": [np.full(9, np.nan), np.full(9, np.nan)], "none": None,
                   "first": [None, np.full(9, np.nan)], "second": [np.full(9, np.nan), None]}[request]
        try:
            ok = cost.Evaluate([p.copy() for p in parameters], residuals, buffers)
        except Exception as exc:  # noqa: BLE001 - say which request failed, keep type and line
            what = {"both": "both jacobians requested",
                    "none": "jacobians=None (Ceres wants residuals only)",
                    "first": "jacobians=[None, J_j] (x_i is a constant block, e.g. a fixed pose)",
                    "second": "jacobians=[J_i, None] (x_j is a constant block)"}[request]
            exc.args = (f"{exc} (called with {what})",)
            raise
        out[f"{request}_ok"] = float(isinstance(ok, (bool, int, np.bool_)) and bool(ok))
        out[f"{request}_r"] = residuals
        out[f"{request}_J"] = np.full(9, np.nan) if buffers is None else next(
            buf for buf in buffers if buf is not None)
        out[f"{request}_J2"] = buffers[1] if request == "both" else np.full(9, np.nan)
    return out
