"""Chapter 2 exercise: solve ``H dx = -b`` densely and sparsely.

Inputs at the edges of the contract (each is a check input):
- dense_solve: n = 1 (a 1 x 1 H)
- upper_triangle_csc: H given as a scipy sparse matrix
- SparseCholeskySolver: an entry of H cancelled to exactly zero and left out (fewer entries)
- SparseCholeskySolver: as many entries as an earlier pattern, at other positions (an explicit zero stored)
- SparseCholeskySolver: two solvers, each with its own pattern, used alternately
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp


def dense_solve(H, b):
    """``dx`` (n,) with ``H dx = -b`` for a dense symmetric positive definite ``H`` (n, n).

    Hint: ``scipy.linalg.cho_factor`` / ``cho_solve``; this costs O(n^3) whatever the
    sparsity, which is the point of comparing it with the sparse solve.
    """
    # BEGIN SOLUTION
    return -scipy.linalg.cho_solve(scipy.linalg.cho_factor(H), b)
    # END SOLUTION


def upper_triangle_csc(H):
    """The upper triangle (diagonal included) of a symmetric ``H`` as a CSC matrix.

    Args: H: (n, n) dense array or scipy sparse matrix. Returns: scipy.sparse CSC (n, n).
    """
    # BEGIN SOLUTION
    return sp.triu(sp.csc_matrix(H), format="csc")
    # END SOLUTION


class SparseCholeskySolver:
    """Sparse ``L D L^T`` solves of ``H dx = -b`` that reuse the analysis of the pattern.

    The first ``solve`` computes a fill-reducing ordering (AMD) and the symbolic
    factorization; later calls with the same sparsity pattern redo only the numeric
    factorization. ``qdldl.Solver(A, upper=True)`` does the first, ``.update(A, upper=True)``
    the second and ``.solve(rhs)`` the triangular solves.

    The pattern is what the CSC matrix stores (``indptr`` and ``indices``), explicit zeros
    included. It can change between calls: ``upper_triangle_csc`` of a dense H leaves out an entry
    that rounding cancelled to exactly zero this time, and not the next. A call whose pattern
    differs from the analysed one is analysed again (a new ``qdldl.Solver``): ``update`` assumes
    the analysed pattern and, given another, silently factorizes the wrong matrix.
    """

    def __init__(self):
        self._solver = None
        self._pattern = None  # (indptr, indices) of the analysed matrix

    def solve(self, H_upper, b):
        """``dx`` (n,) with ``H dx = -b``; ``H_upper`` the upper triangle of H (CSC, (n, n))."""
        import qdldl  # here, not at the top: dense_solve works where qdldl has no wheel (Python 3.15)

        # BEGIN SOLUTION
        H_upper = sp.csc_matrix(H_upper)  # the same pattern stored in another order is analysed again: safe
        same = (self._pattern is not None and np.array_equal(H_upper.indptr, self._pattern[0])
                and np.array_equal(H_upper.indices, self._pattern[1]))
        if same:
            self._solver.update(H_upper, upper=True)
        else:
            self._solver = qdldl.Solver(H_upper, upper=True)
            self._pattern = (H_upper.indptr.copy(), H_upper.indices.copy())
        return -self._solver.solve(np.asarray(b, dtype=float))
        # END SOLUTION
