"""Chapter 1 exercise: the curve-fitting model ``y = exp(a x^2 + b x + c)``.

Inputs at the edges of the contract (each is a check input):
- a single data point (m = 1): r has shape (1,) and J shape (1, 3)

Allowed imports: numpy, scipy.
"""

import numpy as np


def residuals_and_jacobian(params, x, y):
    """Residuals and Jacobian of the exponential model, vectorized over the points.

    Model: ``y_hat_k = exp(a x_k^2 + b x_k + c)`` with ``params = (a, b, c)``.
    Residual: ``r_k = y_hat_k - y_k``. Derive the Jacobian row ``dr_k/d(a, b, c)`` yourself
    (``python -m autograder hint residuals_and_jacobian 1``, then 2 and 3, if you are stuck).

    Args:
        params: (3,) the parameters ``a, b, c``.
        x, y: (m,) sample positions and measured values, m >= 1 (m = 1 included).

    Returns:
        r: (m,) residuals; J: (m, 3) Jacobian ``dr/dparams``.

    Hint: compute ``y_hat`` once and reuse it for every column; no Python loop.
    """
    # BEGIN SOLUTION
    a, b, c = params
    y_hat = np.exp(a * x**2 + b * x + c)
    r = y_hat - y
    J = y_hat[:, None] * np.stack([x**2, x, np.ones_like(x)], axis=1)
    return r, J
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "residuals_and_jacobian": (
        """``y_k`` is data, so ``dr_k/dp = d y_hat_k / dp``. Write ``y_hat_k = exp(u_k)`` with the
        exponent ``u_k = a x_k^2 + b x_k + c``, which is linear in the parameters, and use the chain
        rule.""",
        """``d exp(u) / dp = exp(u) du/dp``, and ``du_k/d(a, b, c) = (x_k^2, x_k, 1)``.""",
        """Jacobian row: ``dr_k/d(a, b, c) = y_hat_k (x_k^2, x_k, 1)``.""",
    ),
}
