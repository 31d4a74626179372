"""Checks of ``ceres_edge_cost.SE2EdgeCost``: the whitened residuals and Jacobians as Ceres
computes them, and ``Evaluate`` with no Jacobian or one block constant.

Public inputs: four of the edges of the edge checks (generic, angle error beyond pi, the
measured angle near pi, just above pi), each with a full square-root information matrix, and
at the edges: the raw angle error exactly pi (full U), a diagonal anisotropic U, and a
symmetric square root U = Omega^(1/2) (not triangular); hidden inputs: the same kinds of edges
from the hidden seed, and other matrices.
"""

from dataclasses import replace
from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import SAME_ANGLE_ATOL, check, failed, values, wrap
from autograder.checks.edges import Edge
from autograder.checks.pose_graph_edge import edges
from autograder.feedback import call_fields, compare

MODULES = ("ceres_edge_cost",)
CERES = "ceres_edge_cost.SE2EdgeCost"
NEEDS = ("pyceres",)  # a peer library: where it has no wheel these checks are not run

# ---------------------------------------------------------------- inputs


@cache
def _ceres_inputs(seed=None):
    """(measurement, U, x_i, x_j, where): full square-root information matrices U (upper, U^T U = Omega)."""
    rng = np.random.default_rng(13 if seed is None else [seed, 231])
    out = []
    for k in (0, 1, 3, 5):
        x_i, x_j, z, where = edges(seed)[k]
        L = rng.normal(size=(3, 3)) * (4.0, 4.0, 8.0)
        omega = L @ L.T + np.diag((3.0, 3.0, 6.0))
        U = np.linalg.cholesky(omega).T
        out.append((z, U, x_i, x_j, where + ", full U"))
    x_i, x_j, z, where = edges(seed)[6]  # theta_j - theta_i - theta_ij exactly pi
    L = rng.normal(size=(3, 3)) * (4.0, 4.0, 8.0)
    out.append((z, np.linalg.cholesky(L @ L.T + np.diag((3.0, 3.0, 6.0))).T, x_i, x_j, where + ", full U"))
    x_i, x_j, z, where = edges(seed)[0]
    diagonal = np.round(np.sort(rng.uniform(0.5, 8.0, 3)) * (1.0, 2.0, 4.0), 3)  # unequal by construction
    out.append((z, np.diag(diagonal), x_i, x_j, where + f", U = diag{tuple(diagonal.tolist())}"))
    x_i, x_j, z, where = edges(seed)[2]
    L = rng.normal(size=(3, 3)) * (4.0, 4.0, 8.0)
    values_, vectors = np.linalg.eigh(L @ L.T + np.diag((3.0, 3.0, 6.0)))
    out.append((z, (vectors * np.sqrt(values_)) @ vectors.T, x_i, x_j,
                where + ", U = Omega^(1/2), symmetric (not triangular)"))
    return out


def _ceres_calls(task):
    def build(seed=None):
        return [Call(f"@autograder.tasks.ceres_edge_cost:{task}", (z, U, x_i, x_j), returns="dict",
                     label="ceres_edge_cost.SE2EdgeCost" + (".evaluate" if task == "ceres_cost" else ".Evaluate"),
                     where=where) for z, U, x_i, x_j, where in _ceres_inputs(seed)]

    return build


# ---------------------------------------------------------------- judges


def _r_as_reference(got, want, call):
    """``got``, read as the reference's ``r = U e`` where it is ``U e`` with the angle error +pi in place
    of -pi (``common.same_angle``: at a raw angle error of exactly pi both are the same angle)."""
    z, U, x_i, x_j = (np.asarray(v, dtype=float) for v in call.args)
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    if got.shape != want.shape or float(wrap(x_j[2] - x_i[2] - z[2])) != -np.pi:
        return got
    other = want + 2.0 * np.pi * U[:, 2]  # U e with e_theta = +pi
    atol = SAME_ANGLE_ATOL * max(1.0, float(np.max(np.abs(want))), float(np.max(np.abs(U))))
    return want if np.allclose(got, other, rtol=1e-9, atol=atol) else got


def _judge_ceres(names):
    causes = {"r": "r = U e", "J_i": "jacobians[0] = U A, row-major", "J_j": "jacobians[1] = U B, row-major"}
    labels = {"r": "residuals[{}]", "J_i": "jacobians[0] as 3x3 [{}]", "J_j": "jacobians[1] as 3x3 [{}]"}
    return values(names, 1e-9, 1e-12, causes, labels, atol_scaled=True, equivalent={"r": _r_as_reference})


def _judge_partial_jacobians(ctx):
    """With jacobians None, [None, J_j] or [J_i, None], Evaluate fills what it is asked for,
    the same as when both Jacobians are requested (the values are graded by the other checks)."""
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, _ in triples:
        both = f"{call.where}, with both jacobians requested"
        if not got["both_ok"]:
            return Verdict(0.0, f"Evaluate did not return True {both}: return True after filling the buffers")
        if np.any(np.isnan(got["both_r"])) or np.any(np.isnan(got["both_J"])) or np.any(np.isnan(got["both_J2"])):
            return Verdict(0.0, f"Evaluate left a buffer unfilled {both}: write into the buffers Ceres gives, "
                                "residuals[:] = ..., jacobians[k][:] = ... (assigning residuals = ... only rebinds "
                                "the name)")
        r = got["both_r"]
        for request, jac, what in (("none", None, "jacobians=None (residuals only)"),
                                   ("first", got["both_J2"], "jacobians=[None, J_j] (x_i constant, e.g. a fixed pose)"),
                                   ("second", got["both_J"], "jacobians=[J_i, None] (x_j constant)")):
            where = f"{call.where}, with {what}"
            if not got[f"{request}_ok"]:
                return Verdict(0.0, f"Evaluate did not return True {where}: return True after filling the buffers")
            text = compare(got[f"{request}_r"], r, "residuals[{}]", 1e-12, 1e-14, where, (),
                           "the residuals must not depend on which Jacobians are requested")
            if text:
                return Verdict(0.0, text)
            if jac is not None:
                text = compare(got[f"{request}_J"], jac, "jacobian[{}]", 1e-12, 1e-14, where, (),
                               "fill each jacobians[k] that is not None, the same as when both are requested")
                if text:
                    return Verdict(0.0, text)
    return Verdict(1.0, "ok")


CHECKS = [
    check(CERES, "residuals r = U e", 2, _ceres_calls("ceres_cost"), _judge_ceres(("r",)), needs=NEEDS),
    check(CERES, "jacobians U A, U B", 3, _ceres_calls("ceres_cost"), _judge_ceres(("J_i", "J_j")), needs=NEEDS),
    check(CERES, "jacobians None or one block constant", 1, _ceres_calls("ceres_partial_jacobians"),
          _judge_partial_jacobians, needs=NEEDS),
]


def _raw_angle_error(call):
    z, _, x_i, x_j = call.args
    return x_j[2] - x_i[2] - z[2]


def _edge(name, holds):
    return Edge(name, "@autograder.tasks.ceres_edge_cost:ceres_cost", holds)


EDGES = (
    _edge("raw angle error theta_j - theta_i - theta_ij exactly pi: r uses e_theta = -pi",
          lambda call: _raw_angle_error(call) == np.pi),
    _edge("information diagonal but anisotropic (U diagonal, unequal entries)",
          lambda call: not np.any(call.args[1] - np.diag(np.diag(call.args[1]))) and np.ptp(np.diag(call.args[1])) > 0),
    _edge("U not triangular (a symmetric square root of Omega)",
          lambda call: bool(np.any(np.tril(call.args[1], -1)) and np.any(np.triu(call.args[1], 1)))),
)

# the edges whose raw angle error is exactly +-pi are written to be exact (angles multiples of 1/16 beside
# pi itself): moving them by an ulp would change the question (autograder.rounding)
CHECKS = [replace(c, exact_inputs=True) for c in CHECKS]
