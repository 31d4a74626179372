# RELEASE: omit
"""Known mistakes in ``gauss_newton`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.gauss_newton import NORMAL, STEP


def normal_mistakes(call, ref):
    J, r, w = call.args
    squeezed = []
    if J.shape[1] == 1:
        squeezed = [(np.squeeze(ref["H"]), "H lost its axes for a single parameter (np.squeeze or float()?): H is "
                                           "(n, n) and b (n,) for every n, n = 1 too")]
    return {
        "H": [
            (J.T @ J, "H ignores the weights: H = J^T W J with W = diag(w)"),
            ((J * w[:, None] ** 2).T @ J, "w is applied twice: scale one factor only, H = (w J)^T J"),
            ((J * np.sqrt(w)[:, None]).T @ J, "use w, not sqrt(w), when scaling one factor: H = (w J)^T J"),
            *squeezed,
        ],
        "b": [
            (J.T @ r, "b ignores the weights: b = J^T W r with W = diag(w)"),
            (-ref["b"], "b has the opposite sign: b = J^T W r (the step then solves H h = -b)"),
            ((J * w[:, None] ** 2).T @ r, "w is applied twice in b: b = J^T W r"),
        ],
    }


def step_mistakes(call, ref):
    H, b = call.args[:2]
    d = call.args[2] if len(call.args) > 2 else None
    h = ref["value"]
    known = [(-h, "h has the opposite sign: the step solves H h = -b")]
    if d is not None:
        known += [
            (np.linalg.solve(H, -b), "the damping is ignored: solve (H + diag(damping)) h = -b"),
            (np.linalg.solve(H + d[None, :], -b),
             "H + damping adds the vector to every row (broadcasting): use H + np.diag(damping)"),
            (-np.linalg.solve(H + d[None, :], -b), "opposite sign and H + damping broadcast to every row"),
        ]
    return {"value": known}


MISTAKES = {
    f"{NORMAL}: unit weights": normal_mistakes,
    f"{NORMAL}: non-uniform weights": normal_mistakes,
    f"{STEP}: undamped step": step_mistakes,
    f"{STEP}: damped step": step_mistakes,
}
