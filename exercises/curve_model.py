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
    raise NotImplementedError("TODO curve_model.residuals_and_jacobian: not implemented yet")
