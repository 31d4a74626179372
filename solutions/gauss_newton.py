"""Chapter 1 exercise: the normal equations and the (damped) Gauss-Newton step.

Inputs at the edges of the contract (each is a check input):
- normal_equations with a single residual (m = 1): H has rank one
- normal_equations with a single parameter (n = 1): H is (1, 1) and b (1,)
- solve_step with a single unknown (n = 1), damped and undamped: h is (1,)

Allowed imports: numpy, scipy.
"""

import numpy as np


def normal_equations(J, r, w):
    """The Gauss-Newton normal equations.

    Linearize the residuals, ``r(p + h) ~ r + J h``, and write the weighted cost of the linearized
    residuals as a quadratic in h: ``(r + J h)^T W (r + J h) = chi2 + 2 b^T h + h^T H h``. Derive
    H and b (``python -m autograder hint normal_equations 1``); the Gauss-Newton step, the
    minimizer of that quadratic, then solves ``H h = -b``.

    Args:
        J: (m, n) Jacobian ``dr/dp``; r: (m,) residuals; w: (m,) weights (W = diag(w));
        m, n >= 1 (one residual or one parameter included).

    Returns:
        H: (n, n) symmetric; b: (n,), as defined above.

    Hint: scale the rows of J by w instead of building the m x m matrix W.
    """
    # BEGIN SOLUTION
    Jw = J * w[:, None]
    return Jw.T @ J, Jw.T @ r
    # END SOLUTION


def solve_step(H, b, damping=None):
    """Solve ``(H + diag(damping)) h = -b`` for the step h.

    Args:
        H: (n, n) symmetric positive (semi)definite, n >= 1; b: (n,);
        damping: (n,) diagonal added to H, or None for the plain Gauss-Newton step.

    Returns:
        h: (n,) the step. Raises ``numpy.linalg.LinAlgError`` when the matrix is
        not positive definite.

    Hint: H is symmetric positive definite: a Cholesky factorization
    ``H = L L^T`` and two triangular solves beat a general inverse.
    """
    # BEGIN SOLUTION
    A = H if damping is None else H + np.diag(damping)
    L = np.linalg.cholesky(A)
    return -np.linalg.solve(L.T, np.linalg.solve(L, b))
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "normal_equations": (
        """Expand the product ``(r + J h)^T W (r + J h)`` term by term and match the terms of degree 0, 1
        and 2 in h. W is symmetric.""",
        """``(J h)^T W r = r^T W J h`` (a scalar equals its transpose), so the linear term is
        ``2 (J^T W r)^T h``; the quadratic term is ``h^T (J^T W J) h``.""",
        """``H = J^T W J`` (n, n) and ``b = J^T W r`` (n,).""",
    ),
}
