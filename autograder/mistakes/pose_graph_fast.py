# RELEASE: omit
"""Known mistakes in ``pose_graph_fast`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.pose_graph_fast import FAST_ASSEMBLER, FAST_EDGES


def edge_mistakes(call, ref):
    graph = call.args[0]
    raw = np.array(ref["e"], dtype=float)
    raw[:, 2] = graph["poses"][graph["edges_j"], 2] - graph["poses"][graph["edges_i"], 2] - graph["measurements"][:, 2]
    return {"e": [(raw, "e[:, 2] is not wrapped to [-pi, pi)"), (-ref["e"], "e has the opposite sign")],
            "A": [(-ref["A"], "A has the opposite sign")], "B": [(-ref["B"], "B has the opposite sign")]}


#: why a sum by fancy index loses terms (the lesson warns of it)
FANCY_INDEX = ("numpy's fancy-index += (data[slots] += values) does not accumulate repeated indices: where "
               "several edges share an entry, only the last one's value is added; sum them with "
               "np.add.at(data, slots, values) or np.bincount(slots, weights=values, minlength=size)")


def last_write_wins(graph, e, A, B):
    """``H`` (dense, upper) and ``b`` of a sum by fancy index (``data[slots] += values``): each entry
    holds the share of the last edge that writes it; the fixed poses then held still as the reference."""
    n = 3 * len(graph["poses"])
    H, b = np.zeros((n, n)), np.zeros(n)
    for i, j, e_k, A_k, B_k, omega in zip(graph["edges_i"], graph["edges_j"], e, A, B, graph["information"]):
        J = np.concatenate([A_k, B_k], axis=1)
        dof = np.concatenate([3 * int(i) + np.arange(3), 3 * int(j) + np.arange(3)])
        block, g = J.T @ omega @ J, J.T @ omega @ e_k
        for a in range(6):
            for c in range(a, 6):
                H[min(dof[a], dof[c]), max(dof[a], dof[c])] = block[a, c]
        b[dof] = g
    fixed = (3 * np.asarray(graph["fixed"], dtype=int)[:, None] + np.arange(3)).ravel()
    H[fixed, :], H[:, fixed], b[fixed] = 0.0, 0.0, 0.0
    H[fixed, fixed] = 1.0
    return H, b


def assembler_mistakes(call, ref):
    graph, blocks = call.args[:2]
    known = {}
    for k in range(2):
        H_ref = np.asarray(ref[f"H{k}"], dtype=float)
        full = H_ref + np.triu(H_ref, 1).T
        H_fancy, b_fancy = last_write_wins(graph, *(np.asarray(v, dtype=float) for v in blocks[k]))
        pairs = [(full, "H holds the whole matrix: store the upper triangle only (diagonal included)"),
                 (np.tril(full), "H holds the lower triangle: store the upper triangle (row <= column)")]
        if not np.allclose(H_fancy, H_ref, rtol=1e-9, atol=0.0):  # no entry shared: the slip gives the same H
            pairs.append((H_fancy, f"H's entries shared by several edges hold one edge's share: {FANCY_INDEX}"))
        if k == 1:
            pairs.append((H_ref + ref["H0"], "the second call added onto the first call's values: "
                                             "start every assemble from zero"))
        known[f"H{k}"] = pairs
        known[f"b{k}"] = [(-ref[f"b{k}"], "b has the opposite sign")]
        if not np.allclose(b_fancy, ref[f"b{k}"], rtol=1e-9, atol=0.0):
            known[f"b{k}"].append((b_fancy, f"b's entries shared by several edges hold one edge's share: "
                                             f"{FANCY_INDEX}"))
    return known


MISTAKES = {
    f"{FAST_EDGES}: e, A, B of all edges": edge_mistakes,
    f"{FAST_ASSEMBLER}: H (upper, CSC), b, chi2": assembler_mistakes,
}
