"""Chapter 6 exercise: chordal initialisation of a 3D pose graph.

From the file's poses (odometry composed, drifting) Gauss-Newton may not reach the global
minimum, or takes many iterations. The chordal start (Carlone, Tron, Daniilidis, Dellaert,
ICRA 2015; GTSAM's ``InitializePose3``) needs no start at all:

1. ``relaxed_rotations``: every edge says ``R_j = R_i R_z``, which is linear in the nine
   entries of the R's. Drop the constraint that each R is a rotation and solve one sparse
   linear least-squares problem for the nine entries of every pose's R (one pose, the
   anchor, held at a given rotation).
2. ``project_to_so3``: the nearest rotation to each 3x3 result (SVD, determinant fixed).
3. ``translations_given_rotations``: with the rotations fixed, the edges' translation
   errors are linear in the positions: a second sparse linear least squares.

``chordal_poses`` (given) chains the three. Conventions as in ``pose_graph_3d``: a pose is
``(R, t)``, edge k measures ``Z_k = (R_z, t_z)``, pose j seen from pose i; the information
(M, 6, 6) is for the error ``[D_t; Log(D_R)]``, translation first.

Inputs at the edges of the contract (each is a check input):
- relaxed_rotations: the anchor not the first pose
- relaxed_rotations: edges written from the larger index to the smaller
- project_to_so3: a matrix of negative determinant (U V^T alone a reflection)
- project_to_so3: a rotation (it stays)
- project_to_so3: an exact reflection -R (the nearest rotation not unique: any of them is right)
- translations_given_rotations: full, correlated 3x3 translation information
- translations_given_rotations: the anchor not the first pose

Allowed imports: numpy, scipy, course.solver.spd.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph

from course.solver.spd import spd_solve


def check_graph(num_poses, edges_i, edges_j, anchor):
    """``(num_poses, edges_i, edges_j, anchor)`` validated: indices in range, the anchor a
    vertex, every vertex reached from the anchor (else the systems below are singular)."""
    num_poses = int(num_poses)
    edges_i, edges_j = np.asarray(edges_i, dtype=np.int64), np.asarray(edges_j, dtype=np.int64)
    if edges_i.shape != edges_j.shape or edges_i.ndim != 1:
        raise ValueError(f"edges_i and edges_j must be (M,) arrays alike, got {edges_i.shape} and {edges_j.shape}")
    for name, edges in (("edges_i", edges_i), ("edges_j", edges_j)):
        if edges.size and (edges.min() < 0 or edges.max() >= num_poses):
            bad = int(np.flatnonzero((edges < 0) | (edges >= num_poses))[0])
            raise ValueError(f"{name}[{bad}] = {edges[bad]} is not a vertex index in [0, {num_poses})")
    if not 0 <= int(anchor) < num_poses:
        raise ValueError(f"anchor must be a vertex index in [0, {num_poses}), got {anchor!r}")
    adjacency = sp.coo_matrix((np.ones(len(edges_i)), (edges_i, edges_j)), shape=(num_poses, num_poses)).tocsr()
    reached = csgraph.breadth_first_order(adjacency, int(anchor), directed=False, return_predecessors=False)
    if len(reached) < num_poses:
        lost = np.setdiff1d(np.arange(num_poses), reached)
        raise ValueError(f"disconnected graph: {len(lost)} vertex(es) not reached from the anchor {anchor}, "
                         f"e.g. {lost[:10].tolist()}")
    return num_poses, edges_i, edges_j, int(anchor)


def unknowns(num_poses, anchor):
    """Every pose's index among the unknowns (all poses but the anchor, in order; -1 for the
    anchor), (N,)."""
    index = np.arange(num_poses) - (np.arange(num_poses) > anchor)
    index[anchor] = -1
    return index


def relaxed_rotations(num_poses, edges_i, edges_j, R_z, weights, R_anchor, anchor=0):
    """The relaxation's 3x3 matrices (N, 3, 3), not yet rotations; row ``anchor`` is ``R_anchor``.

    Minimize, over the nine entries of every pose's R but the anchor's (held at ``R_anchor``)::

        sum_k  w_k || R_j - R_i R_z ||_F^2          (Frobenius norm; i, j the ends of edge k)

    with no constraint that the R's be rotations. It is a linear least-squares problem: derive its
    sparse normal equations, with the anchor eliminated, and solve them
    (``python -m autograder hint relaxed_rotations 1``, then 2 and 3).

    Args: ``weights`` (M,) the rotation weight of each edge (``chordal_poses`` gives
    ``trace(Omega_rot) / 3``); ``R_z`` (M, 3, 3); ``R_anchor`` (3, 3).
    Hint: build H with one ``scipy.sparse.coo_matrix((data, (rows, cols)), shape).tocsc()``
    (duplicates are summed), no Python loop over edges; solve it sparse
    (``scipy.sparse.linalg.splu``, or ``course.solver.spd.spd_solve``: qdldl's LDL^T where installed).
    """
    num_poses, edges_i, edges_j, anchor = check_graph(num_poses, edges_i, edges_j, anchor)
    R_anchor = np.asarray(R_anchor, dtype=float)
    if num_poses == 1:
        return R_anchor[None].copy()
    # BEGIN SOLUTION
    n, w = num_poses, np.asarray(weights, dtype=float)
    R_z = np.asarray(R_z, dtype=float)
    index = unknowns(n, anchor)
    # the 3x3 blocks of H: (row pose, column pose, block), diagonal blocks w I, off-diagonal -w R_z and -w R_z^T
    diagonal = np.bincount(edges_i, w, minlength=n) + np.bincount(edges_j, w, minlength=n)
    eye = np.eye(3)
    block_rows = np.concatenate([np.arange(n), edges_i, edges_j])
    block_cols = np.concatenate([np.arange(n), edges_j, edges_i])
    H_ij, H_ji = -w[:, None, None] * R_z, -w[:, None, None] * R_z.transpose(0, 2, 1)
    blocks = np.concatenate([diagonal[:, None, None] * eye, H_ij, H_ji])
    a, b = np.divmod(np.arange(9), 3)
    rows = (3 * block_rows[:, None] + a).ravel()
    cols = (3 * block_cols[:, None] + b).ravel()
    H = sp.coo_matrix((blocks.reshape(-1, 9).ravel(), (rows, cols)), shape=(3 * n, 3 * n)).tocsc()
    free = np.flatnonzero(np.repeat(index >= 0, 3))
    fixed = np.arange(3 * anchor, 3 * anchor + 3)
    rhs = -(H[free][:, fixed] @ R_anchor.T)  # (3(N-1), 3): one column per row a of the R's
    X = spd_solve(H[free][:, free], np.asarray(rhs))
    out = np.empty((n, 3, 3))
    out[index >= 0] = X.reshape(n - 1, 3, 3).transpose(0, 2, 1)
    out[anchor] = R_anchor
    return out
    # END SOLUTION


def project_to_so3(M):
    """The rotation nearest to each M (K, 3, 3) in the Frobenius norm, (K, 3, 3).

    The nearest orthogonal matrix of determinant +1 (not -1: a reflection is not a rotation);
    derive it from M's singular value decomposition (``python -m autograder hint project_to_so3 1``).
    Where it is not unique (an exact reflection), any nearest rotation is right.
    """
    # BEGIN SOLUTION
    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=float))
    d = np.linalg.det(np.matmul(U, Vt))
    U = U.copy()
    U[:, :, 2] *= d[:, None]
    return np.matmul(U, Vt)
    # END SOLUTION


def translations_given_rotations(num_poses, edges_i, edges_j, t_z, R_z, information, R, t_anchor, anchor=0):
    """Positions t (N, 3) given the rotations R (N, 3, 3); row ``anchor`` is ``t_anchor``.

    With the rotations fixed, minimize over every position but the anchor's (held at ``t_anchor``)
    the translation part of the cost::

        sum_k  e_t^T Omega_tt e_t,     e_t = R_z^T (R_i^T (t_j - t_i) - t_z),     Omega_tt = information[k, :3, :3]

    (the rotation-translation cross terms of the information are ignored, the rotations being
    fixed). ``e_t`` is linear in t: derive the sparse normal equations, with the anchor eliminated,
    and solve them (``python -m autograder hint translations_given_rotations 1``, then 2 and 3).
    """
    num_poses, edges_i, edges_j, anchor = check_graph(num_poses, edges_i, edges_j, anchor)
    t_anchor = np.asarray(t_anchor, dtype=float)
    if num_poses == 1:
        return t_anchor[None].copy()
    # BEGIN SOLUTION
    n = num_poses
    R, R_z, t_z = (np.asarray(v, dtype=float) for v in (R, R_z, t_z))
    Q = np.matmul(R[edges_i], R_z)  # (M, 3, 3)
    W = np.matmul(Q, np.matmul(np.asarray(information, dtype=float)[:, :3, :3], Q.transpose(0, 2, 1)))
    c = np.einsum("mab,mb->ma", R[edges_i], t_z)
    Wc = np.einsum("mab,mb->ma", W, c)
    block_rows = np.concatenate([edges_i, edges_j, edges_i, edges_j])
    block_cols = np.concatenate([edges_i, edges_j, edges_j, edges_i])
    blocks = np.concatenate([W, W, -W, -W])
    a, b = np.divmod(np.arange(9), 3)
    H = sp.coo_matrix((blocks.reshape(-1, 9).ravel(), ((3 * block_rows[:, None] + a).ravel(),
                                                       (3 * block_cols[:, None] + b).ravel())),
                      shape=(3 * n, 3 * n)).tocsc()
    g = np.zeros(3 * n)
    np.add.at(g, (3 * edges_i[:, None] + np.arange(3)).ravel(), -Wc.ravel())
    np.add.at(g, (3 * edges_j[:, None] + np.arange(3)).ravel(), Wc.ravel())
    index = unknowns(n, anchor)
    free = np.flatnonzero(np.repeat(index >= 0, 3))
    fixed = np.arange(3 * anchor, 3 * anchor + 3)
    rhs = g[free] - H[free][:, fixed] @ t_anchor
    t = np.empty((n, 3))
    t[index >= 0] = spd_solve(H[free][:, free], rhs).reshape(-1, 3)
    t[anchor] = t_anchor
    return t
    # END SOLUTION


def chordal_poses(num_poses, edges_i, edges_j, t_z, R_z, information, t_anchor, R_anchor, anchor=0):
    """``(t (N, 3), R (N, 3, 3))``: relaxed rotations (weights ``trace(Omega_rot) / 3``),
    projected, then the translations given them; the anchor held at ``(t_anchor, R_anchor)``."""
    information = np.asarray(information, dtype=float)
    weights = np.trace(information[:, 3:, 3:], axis1=1, axis2=2) / 3.0
    R = project_to_so3(relaxed_rotations(num_poses, edges_i, edges_j, R_z, weights, R_anchor, anchor))
    R[anchor] = R_anchor
    t = translations_given_rotations(num_poses, edges_i, edges_j, t_z, R_z, information, R, t_anchor, anchor)
    return t, R


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "relaxed_rotations": (
        """Split the Frobenius norm into the three rows of the matrices: each row ``a`` gives the same
        linear least-squares problem in the rows ``r^a`` (as column vectors) of every R. Write one edge's
        residual as ``J_i r_i^a + J_j r_j^a``, add ``J^T w J`` into 3x3 blocks of H (3N, 3N), then move the
        anchor's known columns to the right-hand side. The three rows are three right-hand sides of
        one system: one factorization.""",
        """Row a of ``R_i R_z`` is ``(r_i^a)^T R_z``, i.e. the column ``R_z^T r_i^a``: the residual of row a is
        ``r_j^a - R_z^T r_i^a`` (3,), so ``J_i = -R_z^T``, ``J_j = I``. With F the free unknowns and A the
        anchor's, ``[H_FF H_FA] [X_F; X_A] = 0`` becomes ``H_FF X_F = -H_FA X_A``.""",
        """Edge k adds (3x3 blocks at rows/columns ``3i:3i+3``, ``3j:3j+3``)::

            H_ii += w I     H_jj += w I     H_ij += -w R_z     H_ji += -w R_z^T

        Solve ``H_FF X_F = -H_FA X_A`` with ``X_A = R_anchor^T`` (one column of X per row a: the anchor's
        rows as columns), X (3N, 3); then ``R_k[a, :] = X[3k:3k+3, a]``, i.e. pose k's 3x3 block of X
        transposed.""",
    ),
    "project_to_so3": (
        """Expand ``||R - M||_F^2`` for an orthogonal R: only one term depends on R. Put M's SVD into it and
        ask which orthogonal matrix maximizes it, then which rotation does when that one has determinant -1.""",
        """``||R - M||_F^2 = 3 - 2 trace(R^T M) + ||M||_F^2``; with ``M = U S V^T``, ``trace(R^T M) =
        trace(S Z)`` with the orthogonal ``Z = U^T R V``: ``sum_a s_a Z_aa``, largest at ``Z = I``
        (``R = U V^T``). With ``det Z`` forced to ``det(U V^T)``, when that is -1 the best is to flip the
        sign of the term of the smallest singular value: ``Z = diag(1, 1, -1)``.""",
        """``R = U diag(1, 1, d) V^T`` with ``d = det(U V^T)`` (+-1) and ``M = U S V^T`` (numpy's SVD sorts
        the singular values in decreasing order, so the last column of U meets the smallest): multiply U's
        last column by d, then ``U V^T``, batched over K.""",
    ),
    "translations_given_rotations": (
        """Pull the rotations out of ``e_t`` so that it reads ``(a fixed rotation)^T`` times a residual that is
        linear in the positions with ``J_i = -I``, ``J_j = I``; the cost becomes a weighted sum of squares of
        that residual. Assemble H (3N, 3N) and g (3N,) in 3x3 blocks, eliminate the anchor as in
        ``relaxed_rotations``.""",
        """``e_t = R_z^T R_i^T (t_j - t_i - R_i t_z) = (R_i R_z)^T r_k`` with the world-frame residual
        ``r_k = t_j - t_i - c_k``, ``c_k = R_i t_z``; so ``e_t^T Omega_tt e_t = r_k^T W_k r_k`` with
        ``W_k = (R_i R_z) Omega_tt (R_i R_z)^T``. Minimizing ``sum (J t - c)^T W (J t - c)`` gives
        ``J^T W J t = J^T W c``.""",
        """Edge k adds, with ``W = (R_i R_z) Omega_tt (R_i R_z)^T`` and ``c = R_i t_z``::

            H_ii += W    H_jj += W    H_ij += -W    H_ji += -W    g_i -= W c    g_j += W c

        then ``H_FF t_F = g_F - H_FA t_anchor``, solved sparse.""",
    ),
}
