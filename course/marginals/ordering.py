"""A fill-reducing ordering that keeps each variable's block of scalars together.

The marginals' exercise reads variables as consecutive blocks of R's rows, so the scalars are not
ordered one by one: the *variable graph* is (variables ``u`` and ``v`` adjacent when some entry of
``H[block u, block v]`` is stored), and an approximate minimum degree ordering of it (AMD, through
cvxopt where it is installed; else scipy's reverse Cuthill-McKee, which narrows the band and so the
fill of a graph with few loops) is expanded to scalars: variable ``order[0]``'s rows first, each
block in its own order.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from course.core.peers import installed


def variable_graph(H_upper, starts) -> sp.csr_matrix:
    """The (m, m) pattern of H's blocks (symmetric, 1 where ``H[block u, block v]`` stores an entry), from
    ``H_upper`` (n, n) (either triangle, or both) and the blocks' ``starts`` (m + 1,)."""
    m = len(starts) - 1
    owner = np.repeat(np.arange(m), np.diff(starts))
    coo = sp.coo_matrix(H_upper)
    u, v = owner[coo.row], owner[coo.col]
    pattern = sp.csr_matrix((np.ones(len(u)), (np.concatenate([u]), v)), shape=(m, m))
    pattern = pattern + pattern.T + sp.identity(m, format="csr")
    pattern.data[:] = 1.0
    return pattern


def variable_order(pattern) -> np.ndarray:
    """A fill-reducing order (m,) of the variable graph ``pattern`` (m, m) (:func:`variable_graph`)."""
    m = pattern.shape[0]
    if m <= 2:
        return np.arange(m)
    if installed("cvxopt"):
        import cvxopt
        from cvxopt import amd

        lower = sp.tril(pattern, format="coo")
        matrix = cvxopt.spmatrix(1.0, lower.row.astype(np.int64), lower.col.astype(np.int64), (m, m))
        return np.array(amd.order(matrix, uplo="L"), dtype=np.int64).ravel()
    return np.asarray(reverse_cuthill_mckee(sp.csr_matrix(pattern), symmetric_mode=True), dtype=np.int64)


def scalar_permutation(order, starts) -> np.ndarray:
    """The scalars' permutation (n,) of the variables' ``order`` (m,): ``perm[k]`` is the row of H that
    becomes row k; variable ``order[0]``'s rows ``starts[v]:starts[v + 1]`` come first, then the next's."""
    order = np.asarray(order, dtype=np.int64)
    sizes = np.diff(starts)[order]
    first = np.repeat(np.asarray(starts)[order], sizes)
    within = np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return first + within
