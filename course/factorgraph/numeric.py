"""A factor's tangent Jacobians by central differences through the retraction (``ours-numeric``).

``J_a[:, :, j] = (r(x_a (+) h e_j) - r(x_a (+) (-h e_j))) / (2 h)``: 2 d_a residual evaluations per
slot, with a truncation error of order ``h^2`` and a rounding error of order ``eps / h``, so at best
about 1e-10 relative: what automatic differentiation avoids.
"""

import numpy as np

#: the step of the central differences (about eps^(1/3))
STEP = 1e-5


def central_differences(residual, retractions, dims, xs, step: float = STEP):
    """``(r (M, m), [J_a (M, m, d_a)])``, as ``autodiff_factor.tangent_jacobians`` returns them."""
    xs = [np.asarray(x, dtype=float) for x in xs]
    r = np.asarray(residual(*xs), dtype=float)
    blocks = []
    for a, (retract, d) in enumerate(zip(retractions, dims)):
        J = np.empty(r.shape + (d,))
        for j in range(d):
            delta = np.zeros((len(xs[a]), d))
            delta[:, j] = step
            plus = list(xs)
            plus[a] = retract(xs[a], delta)
            minus = list(xs)
            minus[a] = retract(xs[a], -delta)
            J[..., j] = (np.asarray(residual(*plus)) - np.asarray(residual(*minus))) / (2.0 * step)
        blocks.append(J)
    return r, blocks
