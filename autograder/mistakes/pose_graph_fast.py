# RELEASE: omit
"""Known mistakes in ``pose_graph_fast`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.pose_graph_fast import FAST_ASSEMBLER, FAST_EDGES


def edge_mistakes(call, ref):
    graph = call.args[0]
    raw = np.array(ref["e"], dtype=float)
    raw[:, 2] = graph["poses"][graph["edges_j"], 2] - graph["poses"][graph["edges_i"], 2] - graph["measurements"][:, 2]
    at_pi = []
    if np.any(raw[:, 2] == np.pi):  # where the wrap is -pi, arctan2 gives +pi
        plus = np.array(ref["e"], dtype=float)
        plus[raw[:, 2] == np.pi, 2] = np.pi
        at_pi = [(plus, "e[:, 2] = +pi where theta_j - theta_i - theta_ij is exactly pi: the range is [-pi, pi), so "
                        "pi wraps to -pi ((angle + pi) % (2 pi) - pi does; arctan2(sin, cos) leaves +pi)")]
    return {"e": [*at_pi, (raw, "e[:, 2] is not wrapped to [-pi, pi)"), (-ref["e"], "e has the opposite sign")],
            "A": [(-ref["A"], "A has the opposite sign")], "B": [(-ref["B"], "B has the opposite sign")]}


def assembler_mistakes(call, ref):
    known = {}
    for k in range(2):
        H_ref = np.asarray(ref[f"H{k}"], dtype=float)
        full = H_ref + np.triu(H_ref, 1).T
        pairs = [(full, "H holds the whole matrix: store the upper triangle only (diagonal included)"),
                 (np.tril(full), "H holds the lower triangle: store the upper triangle (row <= column)")]
        if k == 1:
            pairs.append((H_ref + ref["H0"], "the second call added onto the first call's values: "
                                             "start every assemble from zero"))
        known[f"H{k}"] = pairs
        known[f"b{k}"] = [(-ref[f"b{k}"], "b has the opposite sign")]
    return known


MISTAKES = {
    f"{FAST_EDGES}: e, A, B of all edges": edge_mistakes,
    f"{FAST_ASSEMBLER}: H (upper, CSC), b, chi2": assembler_mistakes,
}
