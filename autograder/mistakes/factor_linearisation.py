# RELEASE: omit
"""Known mistakes in ``factor_linearisation`` (see ``autograder.mistakes``): H, b and chi2 summed
densely, factor by factor, with one slip."""

import numpy as np

from autograder.checks.factor_linearisation import NAME


def assemble(dims, keys, fixed, groups, *, b_sign=1.0, chi2_scale=1.0, hold="both"):
    """``(H upper (n, n), b, chi2)`` with one slip or none."""
    offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    n = int(offsets[-1])
    H, b, chi2 = np.zeros((n, n)), np.zeros(n), 0.0
    for key, (r, J) in zip(keys, groups):
        key = np.asarray(key)
        r = np.asarray(r, dtype=float)
        J = [np.asarray(block, dtype=float) for block in J]
        for f in range(len(key)):
            for a in range(key.shape[1]):
                rows = slice(offsets[key[f, a]], offsets[key[f, a] + 1])
                b[rows] += b_sign * J[a][f].T @ r[f]
                for c in range(key.shape[1]):
                    cols = slice(offsets[key[f, c]], offsets[key[f, c] + 1])
                    H[rows, cols] += J[a][f].T @ J[c][f]
            chi2 += float(r[f] @ r[f])
    for v in fixed:
        dof = slice(offsets[v], offsets[v + 1])
        if hold in ("both", "H"):
            H[dof, :] = 0.0
            H[:, dof] = 0.0
            H[dof, dof] = np.eye(offsets[v + 1] - offsets[v])
        if hold == "diagonal":  # the diagonal set to 1, the rows and columns left as they are
            H[np.arange(offsets[v], offsets[v + 1]), np.arange(offsets[v], offsets[v + 1])] = 1.0
            b[dof] = 0.0
        if hold == "zero":
            H[dof, :] = 0.0
            H[:, dof] = 0.0
        if hold in ("both", "zero"):
            b[dof] = 0.0
    return np.triu(H), b, chi2_scale * chi2


def upper_only(dims, keys, fixed, groups):
    """The slip of keeping each slot pair's block only where it falls on or above the diagonal: a
    factor whose first variable comes after its second loses its off-diagonal block."""
    offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    H, b, chi2 = assemble(dims, keys, fixed, groups)
    H = np.triu(H)
    for key, (_, J) in zip(keys, groups):
        key = np.asarray(key)
        for f in range(len(key)):
            for a in range(key.shape[1]):
                for c in range(a + 1, key.shape[1]):
                    if key[f, a] > key[f, c]:
                        rows = slice(offsets[key[f, c]], offsets[key[f, c] + 1])
                        cols = slice(offsets[key[f, a]], offsets[key[f, a] + 1])
                        H[rows, cols] -= (np.asarray(J[a][f]).T @ np.asarray(J[c][f])).T
    for v in fixed:
        dof = slice(offsets[v], offsets[v + 1])
        H[dof, :] = 0.0
        H[:, dof] = 0.0
        H[dof, dof] = np.eye(offsets[v + 1] - offsets[v])
    return np.triu(H), b, chi2


SLIPS = [
    (lambda *a: assemble(*a, b_sign=-1.0), "b = sum J^T r: the gradient's sign (the step solves H h = -b)"),
    (lambda *a: assemble(*a, chi2_scale=0.5), "chi2 = sum r^T r, not half of it (that is Ceres' cost)"),
    (lambda *a: assemble(*a, hold="H"), "a fixed variable's entries of b are zero too"),
    (lambda *a: assemble(*a, hold="none"), "a fixed variable is held still: its rows and columns of H are zero "
                                           "but for the identity on its diagonal block, its entries of b zero"),
    (lambda *a: assemble(*a, hold="diagonal"), "a fixed variable's rows and columns of H are zero but for the "
                                               "identity: setting its diagonal to 1 leaves the rest coupled"),
    (lambda *a: assemble(*a, hold="zero"), "a fixed variable keeps the identity on its diagonal block, else H is "
                                           "singular"),
    (upper_only, "the upper triangle is in the variables' order, not the slots': when a factor's first "
                 "variable comes after its second, its block J_a^T J_c lands below the diagonal; keep its "
                 "transpose above"),
]


def _known(call, ref):
    dims, keys, fixed, calls = call.args
    known: dict = {}
    for slip, why in SLIPS:
        for k, groups in enumerate(calls):
            H, b, chi2 = slip(dims, keys, fixed, groups)
            for name, value in ((f"H{k}", H), (f"b{k}", b), (f"chi2{k}", chi2)):
                want = np.asarray(ref[name], dtype=float)
                if not np.allclose(value, want, rtol=1e-12, atol=1e-12 * max(1.0, float(np.max(np.abs(want))))):
                    known.setdefault(name, []).append((np.asarray(value, dtype=float), why))
    return known


MISTAKES = {f"{NAME}: {title}": _known for title in (
    "H, b and chi2 of poses and landmarks", "H, b and chi2 of variables of mixed sizes", "fixed variables held still",
    "one factor of one variable")}
