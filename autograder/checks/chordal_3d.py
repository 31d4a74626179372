"""Checks of ``chordal_3d``: the relaxed rotations (one sparse least squares in the nine entries
of every R), their projection to SO(3), and the translations given the rotations, each graded
alone.

Public inputs: 7 poses turned far from each other, 12 edges (a loop and chords, some written
from the larger index to the smaller), measurements with noise so that the relaxation is not
exact, the anchor pose 2 (not the first), weights from 0.5 to 5; the projection on 8 matrices
(general ones, two with a negative determinant, near-rotations, a rotation, a stretched
reflection); the translations with full, correlated 3x3 information blocks; hidden inputs: the
same kind from the hidden seed, and the projection of six exact reflections, whose nearest
rotation is not unique: the projection is judged by the properties the contract states (a
rotation, as near to M as the reference's), so any nearest rotation keeps full marks.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, values
from autograder.checks.edges import Edge
from autograder.feedback import call_fields
from course.geometry import se3
from course.geometry.so3 import exp_many

MODULES = ("chordal_3d",)
RELAXED = "chordal_3d.relaxed_rotations"
PROJECT = "chordal_3d.project_to_so3"
TRANSLATIONS = "chordal_3d.translations_given_rotations"
ANCHOR = 2


@cache
def graph(seed=None) -> dict:
    """Truth ``t`` (7, 3), ``R``; ``edges_i``, ``edges_j`` (12,); noisy ``t_z``, ``R_z``; ``weights``
    (12,); ``information`` (12, 6, 6) full and positive definite."""
    rng = np.random.default_rng(81 if seed is None else [seed, 281])
    n = 7
    t, R = rng.normal(0, 3.0, (n, 3)), exp_many(rng.normal(0, 1.2, (n, 3)))
    pairs = [(0, 1), (1, 2), (3, 2), (3, 4), (4, 5), (5, 6), (6, 0), (0, 3), (5, 1), (2, 6), (4, 0), (6, 3)]
    ei, ej = (np.array(v) for v in zip(*pairs))
    t_z, R_z = se3.between(t[ei], R[ei], t[ej], R[ej])
    R_z = np.matmul(R_z, exp_many(rng.normal(0, 0.08, (len(ei), 3))))
    t_z = t_z + rng.normal(0, 0.2, t_z.shape)
    L = rng.normal(0, 1.0, (len(ei), 6, 6)) + np.eye(6) * rng.uniform(1.0, 3.0, (len(ei), 6, 1))
    return {"t": t, "R": R, "edges_i": ei, "edges_j": ej, "t_z": t_z, "R_z": R_z,
            "weights": rng.uniform(0.5, 5.0, len(ei)), "information": np.matmul(L, L.transpose(0, 2, 1))}


def _where(g) -> str:
    return f"on a graph of {len(g['t'])} poses and {len(g['edges_i'])} edges, anchor {ANCHOR}"


def _relaxed_calls(seed=None):
    g = graph(seed)
    args = (len(g["t"]), g["edges_i"], g["edges_j"], g["R_z"], g["weights"], g["R"][ANCHOR])
    return [Call("chordal_3d:relaxed_rotations", args, {"anchor": ANCHOR}, where=_where(g))]


def _project_calls(seed=None):
    """Eight matrices with a unique nearest rotation (distinct singular values), then six reflections:
    stretched a little in the public set (still one answer), exact in the hidden set, where every
    ``-R (I - 2 v v^T)`` is a nearest rotation."""
    rng = np.random.default_rng(83 if seed is None else [seed, 283])
    M = rng.normal(0, 1.0, (8, 3, 3))
    for k in (0, 1):  # a negative determinant: U V^T alone is a reflection
        if np.linalg.det(M[k]) > 0:
            M[k, :, 0] *= -1.0
    R = exp_many(rng.normal(0, 1.0, (4, 3)))
    M[4:6] = R[:2] + rng.normal(0, 0.1, (2, 3, 3))  # near rotations, as the relaxation gives
    M[6] = R[2]  # a rotation: stays
    M[7] = -R[3] @ np.diag([1.0, 1.3, 1.7])  # a reflection stretched: singular values 1, 1.3, 1.7
    calls = [Call("chordal_3d:project_to_so3", (M,), where="on 8 matrices: 0-3 general (0 and 1 with a negative "
                                                           "determinant), 4-5 near rotations, 6 a rotation, "
                                                           "7 a stretched reflection")]
    reflections = -exp_many(rng.normal(0, 1.0, (6, 3)))
    if seed is None:  # public data holds only unique answers: these are one singular value from degenerate
        calls.append(Call("chordal_3d:project_to_so3", (reflections @ np.diag([1.0, 1.01, 1.02]),),
                          where="on 6 reflections -R stretched by 1, 1.01, 1.02 (singular values close, but "
                                "distinct: one nearest rotation)"))
    else:
        calls.append(Call("chordal_3d:project_to_so3", (reflections,),
                          where="on 6 exact reflections -R (every singular value 1: the nearest rotation is not "
                                "unique, any of them is right)"))
    return calls


def distances(R, M) -> np.ndarray:
    """``||R_k - M_k||_F`` (K,)."""
    return np.linalg.norm(np.asarray(R, dtype=float) - np.asarray(M, dtype=float), axis=(1, 2))


_PROJECT_VALUES = values(("value",), 1e-9, 1e-11, "U diag(1, 1, det(U V^T)) V^T from the SVD M = U S V^T",
                         {"value": "R[{}]"})


def _judge_project(ctx):
    """By the properties the contract states, since an answer need not be unique (an exact
    reflection): every R_k orthogonal and of determinant +1 (1e-9), and no farther from M_k than
    the reference's rotation (1e-9 relative). Where one is not, the entries against the
    reference's say which and why (known mistakes)."""
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, want in triples:
        R, M = np.asarray(got["value"], dtype=float), np.asarray(call.args[0], dtype=float)
        if R.shape != M.shape or not np.all(np.isfinite(R)):
            return _PROJECT_VALUES(ctx)
        orthogonal = np.abs(np.matmul(R.transpose(0, 2, 1), R) - np.eye(3)).max(axis=(1, 2)) <= 1e-9
        proper = np.abs(np.linalg.det(R) - 1.0) <= 1e-9
        best = distances(want["value"], M)
        nearest = distances(R, M) <= best + 1e-9 * np.maximum(1.0, best)
        bad = np.flatnonzero(~(orthogonal & proper & nearest))
        if len(bad):
            verdict = _PROJECT_VALUES(ctx)
            if verdict.fraction < 1.0:
                return verdict
            k = int(bad[0])
            what = ("is not orthogonal (R^T R != I)" if not orthogonal[k] else
                    f"has determinant {np.linalg.det(R[k]):.6g}, not +1" if not proper[k] else
                    f"is {distances(R, M)[k]:.10g} from M[{k}], farther than the nearest rotation ({best[k]:.10g})")
            return Verdict(0.0, f"R[{k}] {what} {call.where}")
    return Verdict(1.0, "ok")


def _translation_calls(seed=None):
    g = graph(seed)
    rng = np.random.default_rng(85 if seed is None else [seed, 285])
    R = np.matmul(g["R"], exp_many(rng.normal(0, 0.03, (len(g["t"]), 3))))  # rotations near the truth
    R[ANCHOR] = g["R"][ANCHOR]
    args = (len(g["t"]), g["edges_i"], g["edges_j"], g["t_z"], g["R_z"], g["information"], R, g["t"][ANCHOR])
    return [Call("chordal_3d:translations_given_rotations", args, {"anchor": ANCHOR},
                 where=_where(g) + ", full 3x3 translation information, rotations near the truth")]


CHECKS = [
    check(RELAXED, "the relaxation's 3x3 matrices", 3, _relaxed_calls, values(
        ("value",), 1e-7, 1e-9, "minimize sum w ||r_j^a - R_z^T r_i^a||^2 over the rows r^a of every R but the "
                                "anchor's, then R_k[a, :] = X[3k:3k+3, a]", {"value": "R[{}]"})),
    check(PROJECT, "the nearest rotation (SVD, determinant fixed)", 2, _project_calls, _judge_project),
    check(TRANSLATIONS, "positions given the rotations", 3, _translation_calls, values(
        ("value",), 1e-7, 1e-9, "minimize sum r^T W r, r = t_j - t_i - R_i t_z, W = (R_i R_z) Omega_tt (R_i R_z)^T, "
                                "the anchor held", {"value": "t[{}]"})),
]


def _matrices(call) -> np.ndarray:
    return np.asarray(call.args[0], dtype=float)


def _orthogonal(M) -> np.ndarray:
    return np.abs(np.matmul(M.transpose(0, 2, 1), M) - np.eye(3)).max(axis=(1, 2)) <= 1e-12


_TRANSLATIONS = "chordal_3d:translations_given_rotations"

EDGES = (
    Edge("relaxed_rotations: the anchor not the first pose", "chordal_3d:relaxed_rotations",
         lambda c: c.kwargs.get("anchor", 0) != 0),
    Edge("relaxed_rotations: edges written from the larger index to the smaller", "chordal_3d:relaxed_rotations",
         lambda c: bool(np.any(np.asarray(c.args[1]) > np.asarray(c.args[2])))),
    Edge("project_to_so3: a matrix of negative determinant (U V^T alone a reflection)", "chordal_3d:project_to_so3",
         lambda c: bool(np.any(np.linalg.det(_matrices(c)) < 0))),
    Edge("project_to_so3: a rotation (it stays)", "chordal_3d:project_to_so3",
         lambda c: bool(np.any(_orthogonal(_matrices(c)) & (np.linalg.det(_matrices(c)) > 0)))),
    Edge("project_to_so3: an exact reflection -R (the nearest rotation not unique: any of them is right)",
         "chordal_3d:project_to_so3",
         lambda c: bool(np.any(_orthogonal(_matrices(c)) & (np.linalg.det(_matrices(c)) < 0)))),
    Edge("translations_given_rotations: full, correlated 3x3 translation information", _TRANSLATIONS,
         lambda c: bool(np.all(np.abs(np.asarray(c.args[5])[:, :3, :3] - np.eye(3) * np.asarray(c.args[5])[:, :3, :3])
                               .max(axis=(1, 2)) > 0))),
    Edge("translations_given_rotations: the anchor not the first pose", _TRANSLATIONS,
         lambda c: c.kwargs.get("anchor", 0) != 0),
)
