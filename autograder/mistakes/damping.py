# RELEASE: omit
"""Known mistakes in Gavin's damping strategies (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.damping import UPDATE_CASES


def initial_mistakes(kind):
    def mistakes(call, ref):
        diag = call.args[0]
        tau = call.init.get("tau" if kind != 1 else "lambda_0", 1e-2)
        known = {"lam": [], "nu": [(np.array(1.0), "nu starts at 2 (nu_0 = 2)")]}
        if kind == 1:
            known["lam"].append((tau * np.max(diag), "type 1 starts from lambda_0 itself, independent of H "
                                                     "(tau max diag(H) is the start of types 2 and 3)"))
        else:
            known["lam"] += [
                (np.array(tau), "lambda_0 = tau max diag(H), not tau alone"),
                (tau * np.mean(diag), "lambda_0 = tau max diag(H), the largest diagonal entry, not the mean"),
                (tau * np.sum(diag), "lambda_0 = tau max diag(H), not tau trace(H)"),
            ]
        return known

    return mistakes


def diagonal_mistakes(kind):
    def mistakes(call, ref):
        diag, lam = call.args
        if kind == 1:
            return {"value": [
                (lam * np.ones_like(diag), "lambda multiplies the identity where it should multiply diag(H) "
                                           "(type 1, Gavin eq. 13: d = lambda diag(H))"),
                (diag * (1 + lam), "d is only the damping: the loop adds it to H, so leave diag(H) itself out"),
                (diag + lam, "d = lambda diag(H) is a product, not a sum"),
            ]}
        return {"value": [
            (lam * diag, "types 2 and 3 damp with lambda I: d = lambda (1, ..., 1), not lambda diag(H)"),
            (diag + lam, "d is only the damping lambda (1, ..., 1): the loop adds it to H"),
        ]}

    return mistakes


def gain_mistakes(kind):
    def mistakes(call, ref):
        h, b, diag, lam = call.args
        eq16, eq15 = h @ (lam * diag * h - b), h @ (lam * h - b)
        right = eq16 if kind == 1 else eq15
        known = [
            (-right, "opposite sign: the denominator is the decrease of chi2 the model predicts, "
                     "positive for a descent step"),
            (h @ (lam * (diag if kind == 1 else 1.0) * h + b),
             "the sign of b: b = J^T W r is minus Gavin's J^T W (y - y_hat), so the term is -b"),
            (-h @ b, f"the lambda term is missing: h^T ({'lambda diag(H)' if kind == 1 else 'lambda'} h - b)"),
            (0.5 * right, "no factor 1/2: chi2 = r^T W r here, not half of it"),
        ]
        if kind == 1:
            known.insert(0, (eq15, "that is eq. 15 (lambda I, types 2 and 3); type 1 uses eq. 16: "
                                   "h^T (lambda diag(H) h - b)"))
        else:
            known.insert(0, (eq16, "that is eq. 16 (type 1); types 2 and 3 use eq. 15 with lambda I: "
                                   "h^T (lambda h - b)"))
        return {"value": known}

    return mistakes


def update_mistakes(kind):
    def mistakes(call, ref):
        state, rho, accepted = call.args
        alpha, dchi2 = call.kwargs["alpha"], call.kwargs["dchi2"]
        lam, nu = state.lam, state.nu
        known = {"lam": [(np.array(lam), "lambda did not change")], "nu": []}
        add = known["lam"].append
        if kind == 1:
            if accepted:
                add((lam * 11.0, "accept and reject are swapped: an accepted step divides lambda by L_down = 9"))
                add((lam / 11.0, "an accepted step divides by L_down = 9 (L_up = 11 is for rejected steps)"))
                add((lam / 9.0, "lambda is not clamped below: max(lambda / L_down, 1e-7) (lm.m keeps lambda in [1e-7, 1e7])"))
            else:
                add((lam / 9.0, "accept and reject are swapped: a rejected step multiplies lambda by L_up = 11"))
                add((lam * 9.0, "a rejected step multiplies by L_up = 11 (L_down = 9 is for accepted steps)"))
                add((lam * 11.0, "lambda is not clamped above: min(lambda L_up, 1e7) (lm.m keeps lambda in [1e-7, 1e7])"))
        elif kind == 2:
            if accepted:
                add((lam / (1 + alpha), "lambda is not clamped below: max(lambda / (1 + alpha), 1e-7)"))
                add((lam / alpha, "divide by 1 + alpha, not by alpha"))
                add((lam * (1 + alpha), "accepted steps decrease lambda: lambda / (1 + alpha)"))
            else:
                add((lam + abs(dchi2), "the 1/(2 alpha) factor is missing: lambda + |dchi2| / (2 alpha)"))
                add((lam + dchi2 / (2 * alpha), "use |dchi2|: on a rejected step chi2 may still have decreased a little"))
                add((lam + abs(dchi2) * 2 * alpha, "divide |dchi2| by 2 alpha, don't multiply"))
                add((lam + abs(dchi2) / alpha, "the factor 1/2 is missing: lambda + |dchi2| / (2 alpha)"))
                if lam + abs(dchi2) / (2 * alpha) > 1e7:
                    add((1e7, "lambda is clamped at 1e7, but type 2's rejected update has no upper bound: "
                              "lambda + |dchi2| / (2 alpha) (the clamp to [1e-7, 1e7] is type 1's)"))
        else:
            if accepted:
                factor = 1.0 - (2.0 * rho - 1.0) ** 3
                known["nu"].append((np.array(nu), "nu is not reset to 2 after an accepted step (Nielsen: nu = 2)"))
                known["nu"].append((np.array(2 * nu), "an accepted step resets nu to 2; doubling is for rejected steps"))
                add((lam * factor, "the factor is max(1/3, 1 - (2 rho - 1)^3): lambda shrinks by at most 3"))
                add((lam * min(1 / 3, factor), "max(1/3, 1 - (2 rho - 1)^3), not min"))
                if lam * max(1 / 3, factor) < 1e-7:
                    add((1e-7, "lambda is clamped at 1e-7, but type 3 (Nielsen) has no bound on lambda: "
                               "lambda max(1/3, 1 - (2 rho - 1)^3), unclamped"))
            else:
                known["nu"].append((np.array(nu), "nu is not doubled on a rejected step: nu = 2 nu"))
                known["nu"].append((np.array(2.0), "a rejected step doubles nu (nu = 2 nu); the reset to 2 is for accepted steps"))
                add((lam * 2.0, f"multiply lambda by nu (here {nu:g}), not by 2"))
                add((lam * 2 * nu, "multiply lambda by the old nu, then double nu"))
                if lam * nu > 1e7:
                    add((1e7, "lambda is clamped at 1e7, but type 3 (Nielsen) has no bound on lambda: lambda nu, "
                              "unclamped"))
        return known

    return mistakes


def alpha_mistakes(call, ref):
    h, b, chi2, full = call.args
    gh = float(-b @ h)
    raw = gh / ((full - chi2) / 2 + 2 * gh)
    known = [(raw, "alpha is not bounded below: return max(alpha, ALPHA_MIN) with ALPHA_MIN = 0.1")]
    if raw > 1.0:
        known.append((1.0, "alpha is bounded below (0.1) only, not above: where chi2 fell by more than 2 g^T h the "
                           "line search's alpha exceeds 1"))
    for value, why in (
        ((-gh) / ((full - chi2) / 2 - 2 * gh), "g = -b: b = J^T W r is minus Gavin's J^T W (y - y_hat)"),
        (gh / ((full - chi2) + 2 * gh), "the chi2 change is halved in the denominator: (chi2(p+h) - chi2(p)) / 2"),
        (gh / ((chi2 - full) / 2 + 2 * gh), "the chi2 change is chi2(p + h) - chi2(p), not the reverse"),
    ):
        known.append((max(value, 0.1), why))
        known.append((value, why))
    return {"value": known}


def _catalogue():
    out = {}
    for kind in (1, 2, 3):
        ex = f"damping.GavinType{kind}"
        out[f"{ex}: initial_state"] = initial_mistakes(kind)
        out[f"{ex}: damping_diagonal"] = diagonal_mistakes(kind)
        out[f"{ex}: gain_denominator"] = gain_mistakes(kind)
        for title, _, _ in UPDATE_CASES[kind]:
            out[f"{ex}: {title}"] = update_mistakes(kind)
    out["damping.GavinType2: step_scale"] = alpha_mistakes
    return out


MISTAKES = _catalogue()
