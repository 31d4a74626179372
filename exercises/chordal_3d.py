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
    raise NotImplementedError("TODO chordal_3d.relaxed_rotations: not implemented yet")


def project_to_so3(M):
    """The rotation nearest to each M (K, 3, 3) in the Frobenius norm, (K, 3, 3).

    The nearest orthogonal matrix of determinant +1 (not -1: a reflection is not a rotation);
    derive it from M's singular value decomposition (``python -m autograder hint project_to_so3 1``).
    Where it is not unique (an exact reflection), any nearest rotation is right.
    """
    raise NotImplementedError("TODO chordal_3d.project_to_so3: not implemented yet")


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
    raise NotImplementedError("TODO chordal_3d.translations_given_rotations: not implemented yet")


def chordal_poses(num_poses, edges_i, edges_j, t_z, R_z, information, t_anchor, R_anchor, anchor=0):
    """``(t (N, 3), R (N, 3, 3))``: relaxed rotations (weights ``trace(Omega_rot) / 3``),
    projected, then the translations given them; the anchor held at ``(t_anchor, R_anchor)``."""
    information = np.asarray(information, dtype=float)
    weights = np.trace(information[:, 3:, 3:], axis1=1, axis2=2) / 3.0
    R = project_to_so3(relaxed_rotations(num_poses, edges_i, edges_j, R_z, weights, R_anchor, anchor))
    R[anchor] = R_anchor
    t = translations_given_rotations(num_poses, edges_i, edges_j, t_z, R_z, information, R, t_anchor, anchor)
    return t, R
