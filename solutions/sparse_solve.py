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
    # BEGIN SOLUTION
    return -scipy.linalg.cho_solve(scipy.linalg.cho_factor(H), b)
    # END SOLUTION


def upper_triangle_csc(H):
    """The upper triangle (diagonal included) of a symmetric ``H`` as a CSC matrix.

    Args: H: (n, n) dense array or scipy sparse matrix. Returns: scipy.sparse CSC (n, n) holding
    the entries ``H[r, c]`` with ``r <= c`` (a dense H's zeros are not stored)
    (``python -m autograder hint upper_triangle_csc 1``).
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
    the analysed pattern and, given another, silently factorizes the wrong matrix
    (``python -m autograder hint SparseCholeskySolver 1``, then 2 and 3).
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


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "dense_solve": (
        """Factorize ``H = L L^T`` (Cholesky: H is symmetric positive definite), then two triangular
        solves give ``H^-1 b``; the step is its negative.""",
        """``scipy.linalg.cho_factor(H)`` returns the factor (and which triangle it is) in the form
        ``scipy.linalg.cho_solve(factor, rhs)`` takes; ``cho_solve`` solves ``H x = rhs``.""",
        """``dx = -cho_solve(cho_factor(H), b)``.""",
    ),
    "upper_triangle_csc": (
        """Make H a scipy sparse matrix in CSC form (this works from a dense array or any sparse format),
        then keep the entries on and above the diagonal.""",
        """``scipy.sparse.triu(A, k=0, format="csc")`` keeps the entries with ``row <= column`` (``k = 0``: the
        diagonal included) and returns the format asked for; ``scipy.sparse.csc_matrix(dense)`` stores
        only the nonzero entries.""",
        """``sp.triu(sp.csc_matrix(H), format="csc")``.""",
    ),
    "SparseCholeskySolver": (
        """Keep, between calls, the qdldl solver and the pattern it analysed. At each call, compare the
        new matrix's pattern with it: the same pattern, a numeric update; another (or the first call), a new
        solver, and remember its pattern. Then solve and negate.""",
        """A CSC pattern is the pair ``(indptr, indices)``: two matrices have the same pattern when both arrays
        are equal (``np.array_equal``, which is False for different lengths). Store copies, not the
        matrix's own arrays, and make the input CSC first (``sp.csc_matrix``) so that a matrix given in
        another format has those arrays.""",
        """::

            H = sp.csc_matrix(H_upper)
            if a solver exists and (H.indptr, H.indices) equal the stored ones:
                solver.update(H, upper=True)
            else:
                solver = qdldl.Solver(H, upper=True);  pattern = (H.indptr.copy(), H.indices.copy())
            return -solver.solve(b)""",
    ),
}
