# RELEASE: omit
"""Known mistakes in ``pose_graph_assembly.assemble_normal_equations`` (see
``autograder.mistakes``): whole H, b, chi2 assembled from the reference edge blocks of
the call with one slip each; the judges compare the entries their check grades."""

import numpy as np

from autograder.checks.pose_graph_assembly import ASSEMBLY


def assemble(call, *, offdiag="right", information=True, b_sign=1.0, b_swap=False, fix="right",
             outer=False, chi2_scale=1.0):
    """H, b, chi2 assembled from the call's reference blocks, with one mistake or none."""
    poses, ei, ej, _, info, fixed, (E, A, B) = call.args
    n = 3 * len(poses)
    H, b, chi2 = np.zeros((n, n)), np.zeros(n), 0.0
    for k, (i, j) in enumerate(zip(ei, ej)):
        om = info[k] if information else np.eye(3)
        a, bb, e = A[k], B[k], E[k]
        si, sj = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
        if outer:
            H[si, si] += a @ om @ a.T
            H[sj, sj] += bb @ om @ bb.T
        else:
            H[si, si] += a.T @ om @ a
            H[sj, sj] += bb.T @ om @ bb
        ij, ji = a.T @ om @ bb, bb.T @ om @ a
        if offdiag == "right":
            H[si, sj] += ij
            H[sj, si] += ji
        elif offdiag == "swapped":
            H[si, sj] += ji
            H[sj, si] += ij
        elif offdiag == "ij_only":
            H[si, sj] += ij
        elif offdiag == "ji_only":
            H[sj, si] += ji
        elif offdiag == "ij_twice":  # the i,j line's block also put at [j, i]
            H[sj, si] += ij + ji
        gi, gj = a.T @ om @ e, bb.T @ om @ e
        if b_swap:
            gi, gj = gj, gi
        b[si] += b_sign * gi
        b[sj] += b_sign * gj
        chi2 += chi2_scale * float(e @ om @ e)
    held = {"right": fixed, "none": [], "first": [0]}.get(fix, fixed)
    for k in held:
        sk = slice(3 * k, 3 * k + 3)
        H[sk, :] = 0.0
        if fix != "rows":
            H[:, sk] = 0.0
        H[sk, sk] = 0.0 if fix == "no_identity" else np.eye(3)
        if fix != "b_kept":
            b[sk] = 0.0
    return H, b, chi2


H_MISTAKES = (
    ({"offdiag": "swapped"}, "the off-diagonal blocks are swapped: H[i,j] += A^T Omega B (rows of pose i, "
                             "columns of pose j) and H[j,i] += B^T Omega A"),
    ({"offdiag": "ij_only"}, "H[j,i] is missing: add B^T Omega A at rows of pose j, columns of pose i "
                             "(H is symmetric)"),
    ({"offdiag": "ji_only"}, "H[i,j] is missing: add A^T Omega B at rows of pose i, columns of pose j "
                             "(H is symmetric)"),
    ({"offdiag": "ij_twice"}, "the block A^T Omega B is added at [j,i] instead of [i,j]: H[i,j] is rows "
                              "3i:3i+3, columns 3j:3j+3"),
    ({"offdiag": "none"}, "the off-diagonal blocks H[i,j] += A^T Omega B and H[j,i] += B^T Omega A are missing"),
    ({"information": False}, "the information matrix is missing: H[i,i] += A^T Omega A, "
                             "H[i,j] += A^T Omega B, ... with Omega = information[k]"),
    ({"outer": True}, "the diagonal blocks are A^T Omega A and B^T Omega B, not A Omega A^T"),
)
B_MISTAKES = (
    ({"b_sign": -1.0}, "b has the opposite sign: b[i] += A^T Omega e, b[j] += B^T Omega e "
                       "(the step then solves H dx = -b)"),
    ({"information": False}, "the information matrix is missing: b[i] += A^T Omega e"),
    ({"b_swap": True}, "b[i] takes A^T Omega e (A = de/dx_i) and b[j] takes B^T Omega e"),
)
CHI2_MISTAKES = (
    ({"information": False}, "chi2 = sum e^T Omega e: the information matrix is missing"),
    ({"chi2_scale": 0.5}, "chi2 = sum e^T Omega e, without a factor 1/2"),
)


def _fix_mistakes(call):
    fixed = [int(k) for k in call.args[5]]
    why_none = (f"pose{'s' if len(fixed) > 1 else ''} {', '.join(map(str, fixed))} "
                f"{'are' if len(fixed) > 1 else 'is'} not held fixed: zero the rows and columns of "
                "H and the entries of b of every pose in `fixed`, with the identity on its diagonal block")
    mistakes = [({"fix": "none"}, why_none),
                ({"fix": "rows"}, "the columns of the fixed poses must be zeroed too (H stays symmetric)"),
                ({"fix": "no_identity"}, "put the identity on the diagonal block of a fixed pose "
                                         "(else H is singular)"),
                ({"fix": "b_kept"}, "zero b at the fixed poses too (their step must be 0)")]
    if fixed != [0]:
        mistakes.insert(1, ({"fix": "first"}, f"only pose 0 is held fixed: hold every pose in `fixed` "
                                              f"(here {fixed})"))
    return mistakes


def h_mistakes(call, ref):
    return {"H": [(assemble(call, **kw)[0], why) for kw, why in H_MISTAKES]}


def b_mistakes(call, ref):
    return {"b": [(assemble(call, **kw)[1], why) for kw, why in B_MISTAKES],
            "chi2": [(np.array(assemble(call, **kw)[2]), why) for kw, why in CHI2_MISTAKES]}


def fixed_mistakes(call, ref):
    made = [(assemble(call, **kw), why) for kw, why in _fix_mistakes(call)]
    return {"fixed_H": [(out[0], why) for out, why in made], "fixed_b": [(out[1], why) for out, why in made]}


MISTAKES = {
    f"{ASSEMBLY}: H blocks of the free poses": h_mistakes,
    f"{ASSEMBLY}: b and chi2": b_mistakes,
    f"{ASSEMBLY}: fixed poses (first pose, and poses 0 and 3)": fixed_mistakes,
}
