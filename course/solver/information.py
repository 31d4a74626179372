"""Information matrices that are not positive definite, repaired on request.

Every solver here factorizes ``H = sum J^T Omega J`` and needs each edge's information
``Omega`` symmetric positive definite. Some public SE(3) benchmark graphs carry edges whose
matrix is not (an eigenvalue of -1.57e5 beside 1.7e7, say). The readers refuse them by
default, naming file, line and eigenvalues; with ``information="nearest-psd"`` or
``"isotropic"`` they repair those edges (:func:`repair`) and count them. Only the edges that
are not positive definite are touched: a definite matrix is what the file's author measured,
correlations and anisotropy included, and replacing it would change the optimum of graphs
that need no repair.

``nearest-psd``
    The nearest symmetric matrix in the Frobenius norm whose eigenvalues are at least a
    floor ``delta``: with ``B = (A + A^T) / 2 = V diag(lambda) V^T``, it is
    ``V diag(max(lambda, delta)) V^T`` (N. J. Higham, "Computing a nearest symmetric
    positive semidefinite matrix", Linear Algebra Appl. 103, 1988: the nearest positive
    semidefinite matrix is ``V diag(max(lambda, 0)) V^T``; applied to ``B - delta I`` it gives
    the floor). ``delta = FLOOR * max(lambda)``, ``FLOOR = 1e-9``: at 0 the result would only be
    semidefinite, and a singular information on an edge the graph cannot do without (a
    bridge) makes ``H`` singular; relative to the largest eigenvalue so that it does not
    depend on the units, and small enough (condition number at most 1e9, well inside double
    precision's 1e16) that a direction the file gave no information about stays all but
    uninformative, as it is at 0, while the factorization stays accurate.
``isotropic``
    A scaled identity per block (translation, rotation), the cross terms dropped, with
    SE-Sync's weights: its g2o reader (D. M. Rosen et al., SE-Sync, ``read_g2o_file`` in
    ``SESync_utils.cpp``) replaces each information block ``Omega_b`` of dimension ``d`` by the
    isotropic precision that minimises the information divergence, ``d / tr(Omega_b^-1)``
    (its ``tau`` for the translation; its ``kappa`` for the rotation is half that value, the
    concentration of its Langevin noise, whose precision is ``2 kappa``; in 2D it takes the
    rotation's single entry as it is). SE-Sync applies the rule to every edge, because its
    problem is posed for isotropic noise; here it repairs the bad edges alone (see above).
    The rule needs a definite block: a block's eigenvalues that are not positive are raised to
    the floor above first.

A matrix with no positive eigenvalue at all carries no information to keep: no repair
applies (:class:`NoInformationError`).
"""

import numpy as np

#: the readers' ``information=`` options; ``strict`` (the default) refuses such an edge
MODES = ("strict", "nearest-psd", "isotropic")
#: the smallest eigenvalue after a repair, relative to the matrix's largest
FLOOR = 1e-9
#: what a reader's refusal suggests
HINT = ("to repair such edges, read the graph with information='nearest-psd' or 'isotropic' "
        "(python -m course compare DATASET --information nearest-psd|isotropic)")


class NoInformationError(ValueError):
    """A matrix with no positive eigenvalue: no repair applies. ``index``: which one."""

    def __init__(self, index: int, message: str):
        super().__init__(message)
        self.index = index


def check_mode(mode: str) -> str:
    """``mode`` if it is one of :data:`MODES`, else ``ValueError`` listing them."""
    if mode not in MODES:
        raise ValueError(f"unknown information repair {mode!r}; choose one of {', '.join(MODES)}")
    return mode


def not_definite(information) -> np.ndarray:
    """(M,) bool: which of the (M, n, n) symmetric matrices are not positive definite (smallest
    eigenvalue <= 0)."""
    information = np.asarray(information, dtype=float)
    if len(information) == 0:
        return np.zeros(0, dtype=bool)
    return np.linalg.eigvalsh(information)[:, 0] <= 0.0


def nearest_spd(A, floor: float = FLOOR) -> np.ndarray:
    """The nearest symmetric matrix (Frobenius norm) to each of ``A`` (..., n, n) whose
    eigenvalues are at least ``floor`` times its largest (see the module docstring). A matrix
    whose eigenvalues already are comes back as its symmetric part, unchanged. ``ValueError``
    when a matrix has no positive eigenvalue."""
    A = np.asarray(A, dtype=float)
    B = 0.5 * (A + np.swapaxes(A, -1, -2))
    lam, V = np.linalg.eigh(B)
    delta = _delta(lam, floor)
    clipped = np.maximum(lam, delta[..., None])
    out = np.einsum("...ij,...j,...kj->...ik", V, clipped, V)
    out = 0.5 * (out + np.swapaxes(out, -1, -2))
    keep = (lam[..., 0] >= delta)[..., None, None]
    return np.where(keep, B, out)


def isotropic(A, blocks, floor: float = FLOOR) -> np.ndarray:
    """Each of ``A`` (..., n, n) as ``diag(w_1 I, w_2 I, ...)`` over ``blocks`` (tuples of
    indices covering 0..n-1), ``w_b = d_b / tr(A_bb^-1)``, SE-Sync's isotropic weight (see the
    module docstring); a block's eigenvalues that are not positive count as ``floor`` times the
    matrix's largest. ``ValueError`` when a matrix has no positive eigenvalue."""
    A = np.asarray(A, dtype=float)
    B = 0.5 * (A + np.swapaxes(A, -1, -2))
    delta = _delta(np.linalg.eigvalsh(B), floor)
    out = np.zeros_like(B)
    for block in blocks:
        block = np.asarray(block)
        lam = np.linalg.eigvalsh(B[..., block[:, None], block[None, :]])
        lam = np.where(lam > 0.0, lam, delta[..., None])
        weight = len(block) / np.sum(1.0 / lam, axis=-1)
        out[..., block, block] = weight[..., None]
    return out


def repair(information, mode: str, blocks, floor: float = FLOOR) -> tuple[np.ndarray, np.ndarray]:
    """``(information, repaired)``: the (M, n, n) matrices with those that are not positive
    definite repaired by ``mode`` (``nearest-psd`` or ``isotropic``; ``blocks`` for the latter),
    the others untouched, and the (M,) mask of the repaired ones. ``strict`` repairs nothing
    (the reader refuses instead). :class:`NoInformationError` naming the first matrix with no
    positive eigenvalue."""
    check_mode(mode)
    information = np.array(information, dtype=float)
    if mode == "strict":
        return information, np.zeros(len(information), dtype=bool)
    bad = not_definite(information)
    if not bad.any():
        return information, bad
    hopeless = np.linalg.eigvalsh(information[bad])[:, -1] <= 0.0
    if hopeless.any():
        k = int(np.flatnonzero(bad)[np.argmax(hopeless)])
        raise NoInformationError(k, f"information matrix has no positive eigenvalue (eigenvalues "
                                    f"{eigenvalues_text(information[k])}): no information to keep, no repair "
                                    "applies")
    if mode == "nearest-psd":
        information[bad] = nearest_spd(information[bad], floor)
    else:
        information[bad] = isotropic(information[bad], blocks, floor)
    return information, bad


def _delta(lam, floor):
    """``floor`` times the largest of the ascending eigenvalues ``lam`` (..., n); ``ValueError``
    if it is not positive."""
    largest = lam[..., -1]
    if np.any(largest <= 0.0):
        raise ValueError("a matrix with no positive eigenvalue has no nearest positive definite one at a floor "
                         "relative to its largest eigenvalue")
    return floor * largest


def eigenvalues_text(matrix) -> str:
    """The eigenvalues of a symmetric ``matrix``, ascending, on one line: ``[-893766, 400, ...]``."""
    return "[" + ", ".join(f"{v:.6g}" for v in np.linalg.eigvalsh(np.asarray(matrix, dtype=float))) + "]"

