# RELEASE: omit
"""Known mistakes in ``curve_model.residuals_and_jacobian`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.curve_model import COLUMN_HINTS, NAME


def r_mistakes(call, ref):
    p, x, y = call.args
    a, b, c = p
    known = [
        (-ref["r"], "r has the opposite sign: r = y_hat - y (model minus measurement)"),
        (ref["r"] + y, "r is y_hat: subtract the measurement, r = y_hat - y"),
        (np.exp(a * x + b * x**2 + c) - y, "a and b are swapped: y_hat = exp(a x^2 + b x + c)"),
    ]
    if len(x) == 1:
        known.append((np.asarray(ref["r"]).reshape(()), "r lost its axis on a single data point (np.squeeze or "
                                                        "float()?): r has shape (m,) for every m, m = 1 too"))
    return {"r": known}


def column_mistakes(call, ref):
    """Keys ``J0``, ``J1``, ``J2``: wrong versions of each column of J."""
    x, y = call.args[1], call.args[2]
    y_hat = ref["r"] + y
    powers = (x**2, x, np.ones_like(x))
    known = {}
    for j in range(3):
        col = ref["J"][:, j]
        pairs = [(-col, f"J[:, {j}] has the opposite sign: J = dr/dp and r = y_hat - y, "
                        f"so J = +y_hat (x^2, x, 1)"),
                 (powers[j], f"the chain-rule factor y_hat is missing: d exp(u) / dp = "
                             f"exp(u) du/dp, so {COLUMN_HINTS[j][6:]}")]
        for k in range(3):
            if k != j:
                pairs.append((powers[k] * y_hat, f"{COLUMN_HINTS[j]} (your column {j} is column {k}'s "
                                                 "derivative: wrong power of x)"))
        known[f"J{j}"] = pairs
    return known


MISTAKES = {
    f"{NAME}: r values": r_mistakes,
    f"{NAME}: J values": column_mistakes,
}
