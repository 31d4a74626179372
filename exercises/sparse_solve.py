"""Chapter 2 exercise: solve ``H dx = -b`` densely and sparsely.

Inputs at the edges of the contract (each is a check input):
- dense_solve: n = 1 (a 1 x 1 H)
- upper_triangle_csc: H given as a scipy sparse matrix
- SparseCholeskySolver: an entry of H cancelled to exactly zero and left out (fewer entries)
- SparseCholeskySolver: as many entries as an earlier pattern, at other positions (an explicit zero stored)
- SparseCholeskySolver: two solvers, each with its own pattern, used alternately

Allowed imports: numpy, scipy, qdldl.
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp


def dense_solve(H, b):
    """``dx`` (n,) with ``H dx = -b`` for a dense symmetric positive definite ``H`` (n, n).

    Use a dense factorization that exploits the symmetry and the positive definiteness; it costs
    O(n^3) whatever the sparsity, which is the point of comparing it with the sparse solve
    (``python -m autograder hint dense_solve 1``).
    """
    raise NotImplementedError("TODO sparse_solve.dense_solve: not implemented yet")


def upper_triangle_csc(H):
    """The upper triangle (diagonal included) of a symmetric ``H`` as a CSC matrix.

    Args: H: (n, n) dense array or scipy sparse matrix. Returns: scipy.sparse CSC (n, n) holding
    the entries ``H[r, c]`` with ``r <= c`` (a dense H's zeros are not stored)
    (``python -m autograder hint upper_triangle_csc 1``).
    """
    raise NotImplementedError("TODO sparse_solve.upper_triangle_csc: not implemented yet")


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
    the analysed pattern and, given another, silently factorizes the wrong matrix
    (``python -m autograder hint SparseCholeskySolver 1``, then 2 and 3).
    """

    def __init__(self):
        self._solver = None
        self._pattern = None  # (indptr, indices) of the analysed matrix

    def solve(self, H_upper, b):
        """``dx`` (n,) with ``H dx = -b``; ``H_upper`` the upper triangle of H (CSC, (n, n))."""
        import qdldl  # here, not at the top: dense_solve works where qdldl has no wheel (Python 3.15)

        raise NotImplementedError("TODO sparse_solve.SparseCholeskySolver.solve: not implemented yet")
