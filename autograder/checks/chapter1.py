"""Chapter 1 checks: the curve model, the normal equations and step, Gavin's damping types.

Each function is graded alone on reference inputs, so one bug costs one check (and at
most the end-to-end run that uses it). Points: see ``CHECKS`` (``python -m autograder
--list``). The end-to-end checks run ``course.solvers.minimize`` in the child:
Gauss-Newton with the student's model and normal equations, and each LM type with the
student's damping strategy on the reference model.
"""

from functools import lru_cache

import numpy as np

from autograder.checks import Call, Check, Verdict
from autograder.compare import call_fields, compare, fmt, values

MODULES = ("curve_model", "gauss_newton", "damping")

CURVE = "curve_model.residuals_and_jacobian"
NORMAL = "gauss_newton.normal_equations"
STEP = "gauss_newton.solve_step"
END = "end_to_end"

# ---------------------------------------------------------------- inputs


@lru_cache(maxsize=None)
def _data():
    from course.problems.curve import generate

    return generate(), generate(num_points=20, seed=5, truth=(0.5, -1.0, 0.3))


def _curve_points():
    """(x, y, params, where) at the start, the truth, and two other points."""
    big, small = _data()
    return [
        (big.x, big.y, np.array([0.0, 0.0, 0.0]), "at params (0, 0, 0) (the start)"),
        (big.x, big.y, np.array([1.0, 2.0, 1.0]), "at params (1, 2, 1) (the truth)"),
        (big.x, big.y, np.array([0.3, -0.7, 0.2]), "at params (0.3, -0.7, 0.2)"),
        (small.x, small.y, np.array([0.8, 1.5, 0.9]), "at params (0.8, 1.5, 0.9) on 20 points"),
    ]


def _curve_call(x, y, p, where):
    return Call("curve_model:residuals_and_jacobian", (p, x, y), returns=("r", "J"), where=where)


def _spd(n, seed, scales):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3 * n, n)) * np.asarray(scales, float)
    return A.T @ A + 0.05 * np.eye(n), rng.normal(size=n) * 3.0


# Two small systems with a non-uniform diagonal (so lambda I and lambda diag(H) differ).
SYSTEMS = [_spd(3, 1, [1.0, 6.0, 0.3]), _spd(4, 2, [2.0, 0.5, 4.0, 1.0])]


def _diag_h():
    return [np.diag(H).copy() for H, _ in SYSTEMS]


def _state(lam, nu=2.0):
    from course.damping import DampingState

    return DampingState(lam=lam, nu=nu)


# ---------------------------------------------------------------- curve model

COLUMN_HINTS = (
    "check d y_hat / d a = x^2 y_hat",
    "check d y_hat / d b = x y_hat",
    "check d y_hat / d c = y_hat",
)


def _curve_calls():
    return [_curve_call(*point) for point in _curve_points()]


def _judge_shapes(ctx):
    triples, failure = call_fields(ctx)
    for call, got, _ in triples:
        m = len(call.args[1])
        for name, shape in (("r", (m,)), ("J", (m, 3))):
            if got[name].shape != shape:
                text = f"{name} has shape {got[name].shape}, expected {shape} {call.where}"
                if name == "J" and got[name].shape == shape[::-1]:
                    text += ": J is transposed (one row per point, columns d/da, d/db, d/dc)"
                return Verdict(0.0, text)
    return failure or Verdict(1.0, "ok")


def _r_mistakes(call, ref):
    p, x, y = call.args
    a, b, c = p
    return {"r": [
        (-ref["r"], "r has the opposite sign: r = y_hat - y (model minus measurement)"),
        (ref["r"] + y, "r is y_hat: subtract the measurement, r = y_hat - y"),
        (np.exp(a * x + b * x**2 + c) - y, "a and b are swapped: y_hat = exp(a x^2 + b x + c)"),
    ]}


def _column_mistakes(j, x, y_hat, J_ref):
    col = J_ref[:, j]
    known = [(-col, f"J[:, {j}] has the opposite sign: J = dr/dp and r = y_hat - y, "
                    f"so J = +y_hat (x^2, x, 1)")]
    powers = (x**2, x, np.ones_like(x))
    known.append((powers[j], f"the chain-rule factor y_hat is missing: d exp(u) / dp = "
                             f"exp(u) du/dp, so {COLUMN_HINTS[j][6:]}"))
    for k in range(3):
        if k != j:
            known.append((powers[k] * y_hat, f"{COLUMN_HINTS[j]} (your column {j} is column {k}'s "
                                             f"derivative: wrong power of x)"))
    return known


def _judge_jacobian(ctx):
    triples, failure = call_fields(ctx)
    for call, got, want in triples:
        if got["J"].shape != want["J"].shape:
            return Verdict(0.0, compare(got["J"], want["J"], "J", 0, 0, call.where))
        x, y = call.args[1], call.args[2]
        y_hat = want["r"] + y
        for j in range(3):
            text = compare(got["J"][:, j], want["J"][:, j], f"J[{{}}, {j}]", 1e-8, 1e-10, call.where,
                           _column_mistakes(j, x, y_hat, want["J"]), COLUMN_HINTS[j])
            if text:
                return Verdict(0.0, text)
    return failure or Verdict(1.0, "ok")


FD_POINTS = (1, 2, 3)  # indices into _curve_points(): truth, (0.3, -0.7, 0.2), small data


def _fd_calls():
    calls = []
    points = _curve_points()
    for k in FD_POINTS:
        x, y, p, where = points[k]
        calls.append(_curve_call(x, y, p, where))
        for j in range(3):
            step = 1e-6 * max(1.0, abs(p[j]))
            for sign in (1.0, -1.0):
                q = p.copy()
                q[j] += sign * step
                calls.append(_curve_call(x, y, q, f"{where}, param {j} {'+' if sign > 0 else '-'} {step:g}"))
    return calls


def _judge_finite_differences(ctx):
    """J of the student against central differences of the student's own r, per column."""
    triples, failure = call_fields(ctx)
    if failure:
        return failure
    fields = [got for _, got, _ in triples]
    good = [True, True, True]
    messages, minus = {}, []
    for block in range(len(FD_POINTS)):
        base = 7 * block
        call, J = ctx.calls[base], fields[base]["J"]
        m = len(call.args[1])
        if J.shape != (m, 3) or any(fields[base + i]["r"].shape != (m,) for i in range(7)):
            return Verdict(0.0, f"r or J has the wrong shape {call.where} (see the shapes check)")
        p = call.args[0]
        for j in range(3):
            step = 1e-6 * max(1.0, abs(p[j]))
            fd = (fields[base + 1 + 2 * j]["r"] - fields[base + 2 + 2 * j]["r"]) / (2 * step)
            if not good[j]:
                continue
            if not np.all(np.isfinite(fd)):
                good[j] = False
                messages[j] = (f"your r is not finite near {call.where} (perturbing param {j}), so J[:, {j}] "
                               "cannot be checked by finite differences (see the r values check)")
                continue
            atol = 1e-6 * max(1.0, float(np.max(np.abs(fd))))
            if compare(J[:, j], fd, "", 1e-6, atol) is None:
                continue
            good[j] = False
            excess = np.abs(J[:, j] - fd) - (atol + 1e-6 * np.abs(fd))
            k = int(np.nanargmax(np.where(np.isfinite(excess), excess, np.inf)))
            text = (f"J[:, {j}] disagrees with finite differences of your r {call.where}: "
                    f"J[{k}, {j}] = {fmt(J[k, j])}, central difference {fmt(fd[k])} "
                    f"(rtol=1e-06, atol={atol:.2g})")
            if np.all(np.isfinite(J[:, j])) and compare(J[:, j], -fd, "", 1e-6, atol) is None:
                text += ": J is minus the derivative of your r"
                minus.append(j)
            else:
                text += f": {COLUMN_HINTS[j]}"
            messages[j] = text
    if minus and len(minus) == len(messages):
        columns = ", ".join(f"J[:, {j}]" for j in minus)
        first = messages[minus[0]].split(": J is minus")[0]
        messages = {0: (f"{first}: J is minus the derivative of your r in {columns}; J must be dr/dp "
                        "of the same r (r = y_hat - y gives J = +y_hat (x^2, x, 1))")}
    score = sum(good) / 3.0
    if score == 1.0:
        return Verdict(1.0, "ok")
    return Verdict(score, "; ".join(messages[j] for j in sorted(messages)))


# ---------------------------------------------------------------- normal equations


def _least_squares_inputs(seed, m, n, weights):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m, n))
    r = rng.normal(size=m)
    w = np.ones(m) if weights == "unit" else rng.uniform(0.2, 3.0, size=m)
    return J, r, w


def _normal_calls(weights):
    def build():
        calls = []
        for seed, m, n in ((3, 12, 3), (4, 30, 5)):
            J, r, w = _least_squares_inputs(seed, m, n, weights)
            where = f"for J of shape ({m}, {n}) with {'unit' if weights == 'unit' else 'non-uniform'} weights"
            calls.append(Call("gauss_newton:normal_equations", (J, r, w), returns=("H", "b"), where=where))
        return calls

    return build


def _normal_mistakes(call, ref):
    J, r, w = call.args
    return {
        "H": [
            (J.T @ J, "H ignores the weights: H = J^T W J with W = diag(w)"),
            ((J * w[:, None] ** 2).T @ J, "w is applied twice: scale one factor only, H = (w J)^T J"),
            ((J * np.sqrt(w)[:, None]).T @ J, "use w, not sqrt(w), when scaling one factor: H = (w J)^T J"),
        ],
        "b": [
            (J.T @ r, "b ignores the weights: b = J^T W r with W = diag(w)"),
            (-ref["b"], "b has the opposite sign: b = J^T W r (the step then solves H h = -b)"),
            ((J * w[:, None] ** 2).T @ r, "w is applied twice in b: b = J^T W r"),
        ],
    }


# ---------------------------------------------------------------- solve_step


def _step_calls(damped):
    def build():
        calls = []
        rng = np.random.default_rng(7)
        for H, b in SYSTEMS:
            n = len(b)
            if damped:
                d = rng.uniform(0.3, 2.0, size=n) * np.diag(H)
                calls.append(Call("gauss_newton:solve_step", (H, b, d), where=f"with H of size {n} and damping {fmt(d)}"))
            else:
                calls.append(Call("gauss_newton:solve_step", (H, b), where=f"with H of size {n}, no damping"))
                calls.append(Call("gauss_newton:solve_step", (H, b, None), where=f"with H of size {n}, damping=None"))
        return calls

    return build


def _step_mistakes(call, ref):
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


# ---------------------------------------------------------------- damping strategies

T1, T2, T3 = "damping.GavinType1", "damping.GavinType2", "damping.GavinType3"
LAM_RTOL, LAM_ATOL = 1e-10, 0.0


def _target(cls, method):
    return f"damping:{cls}.{method}"


def _initial_calls(cls, custom):
    """With the default constructor and with a custom lambda_0 / tau (``custom``)."""

    def build():
        diag = _diag_h()[0]
        calls = []
        for init in ({}, custom):
            made = f" with {cls}({', '.join(f'{k}={v}' for k, v in init.items())})" if init else ""
            calls.append(Call(_target(cls, "initial_state"), (diag,), init=init, returns="state",
                              where=f"for diag(H) = {fmt(diag)}{made}"))
        return calls

    return build


def _initial_mistakes(kind):
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


def _diagonal_calls(cls):
    def build():
        return [Call(_target(cls, "damping_diagonal"), (diag, lam), where=f"for diag(H) = {fmt(diag)}, lambda = {lam}")
                for diag, lam in zip(_diag_h(), (0.07, 2.5))]

    return build


def _diagonal_mistakes(kind):
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


def _step_for(H, b, d):
    return np.linalg.solve(H + np.diag(d), -b)


def _gain_calls(cls, kind):
    def build():
        calls = []
        for (H, b), lam in zip(SYSTEMS, (0.01, 3.0)):
            diag = np.diag(H).copy()
            h = _step_for(H, b, lam * diag if kind == 1 else lam * np.ones_like(diag))
            calls.append(Call(_target(cls, "gain_denominator"), (h, b, diag, lam),
                              where=f"for a step of size {len(h)} with lambda = {lam}"))
        return calls

    return build


def _gain_mistakes(kind):
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


def _update_call(cls, state, rho, accepted, alpha=1.0, dchi2=0.0):
    where = (f"for lambda = {state.lam:g}, nu = {state.nu:g}, rho = {rho:g}, "
             f"{'accepted' if accepted else 'rejected'}" + (f", alpha = {alpha:g}, dchi2 = {dchi2:g}" if cls == "GavinType2" else ""))
    return Call(_target(cls, "update"), (state, rho, accepted), {"alpha": alpha, "dchi2": dchi2},
                returns="state", where=where)


def _update_calls(cls, cases):
    def build():
        return [_update_call(cls, _state(*state), *rest) for state, *rest in cases]

    return build


def _update_mistakes(kind):
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
        else:
            if accepted:
                factor = 1.0 - (2.0 * rho - 1.0) ** 3
                known["nu"].append((np.array(nu), "nu is not reset to 2 after an accepted step (Nielsen: nu = 2)"))
                known["nu"].append((np.array(2 * nu), "an accepted step resets nu to 2; doubling is for rejected steps"))
                add((lam * factor, "the factor is max(1/3, 1 - (2 rho - 1)^3): lambda shrinks by at most 3"))
                add((lam * min(1 / 3, factor), "max(1/3, 1 - (2 rho - 1)^3), not min"))
            else:
                known["nu"].append((np.array(nu), "nu is not doubled on a rejected step: nu = 2 nu"))
                known["nu"].append((np.array(2.0), "a rejected step doubles nu (nu = 2 nu); the reset to 2 is for accepted steps"))
                add((lam * 2.0, f"multiply lambda by nu (here {nu:g}), not by 2"))
                add((lam * 2 * nu, "multiply lambda by the old nu, then double nu"))
        return known

    return mistakes


def _alpha_calls():
    calls = []
    H, b = SYSTEMS[0]
    h = _step_for(H, b, 0.05 * np.ones(len(b)))
    gh = float(-b @ h)
    chi2 = 50.0
    for change, what in ((gh, "chi2 rose by g^T h"), (-1.5 * gh, "chi2 fell by 1.5 g^T h"),
                         (1e6 * gh, "chi2 rose a lot (alpha hits its lower bound)")):
        calls.append(Call(_target("GavinType2", "step_scale"), (h, b, chi2, chi2 + change),
                          where=f"for chi2 = {chi2:g}, chi2(p + h) = {chi2 + change:.6g} ({what})"))
    return calls


def _alpha_mistakes(call, ref):
    h, b, chi2, full = call.args
    gh = float(-b @ h)
    raw = gh / ((full - chi2) / 2 + 2 * gh)
    known = [(raw, "alpha is not bounded below: return max(alpha, ALPHA_MIN) with ALPHA_MIN = 0.1")]
    for value, why in (
        ((-gh) / ((full - chi2) / 2 - 2 * gh), "g = -b: b = J^T W r is minus Gavin's J^T W (y - y_hat)"),
        (gh / ((full - chi2) + 2 * gh), "the chi2 change is halved in the denominator: (chi2(p+h) - chi2(p)) / 2"),
        (gh / ((chi2 - full) / 2 + 2 * gh), "the chi2 change is chi2(p + h) - chi2(p), not the reverse"),
    ):
        known.append((max(value, 0.1), why))
        known.append((value, why))
    return {"value": known}


# ---------------------------------------------------------------- end to end


def _end_calls(method):
    def build():
        kwargs = {} if method == "gauss-newton" else {"problem_impl": "solutions"}
        label = (f"minimize(curve problem, {method!r})"
                 + (" with your curve_model and gauss_newton" if method == "gauss-newton"
                    else f" with your damping strategy on the reference model"))
        return [Call("@autograder.tasks:minimize_curve", (method,), kwargs, returns="dict", label=label)]

    return build


def _judge_end(method):
    def judge(ctx):
        triples, failure = call_fields(ctx)
        if failure:
            return failure
        _, got, want = triples[0]
        params = compare(got["params"], want["params"], "params", 1e-6, 1e-9)
        chi2 = compare(got["final_chi2"], want["final_chi2"], "final chi2", 1e-6, 0.0)
        if params is None and chi2 is None:
            return Verdict(1.0, f"ok (chi2 {float(got['final_chi2']):.6g} after {int(got['iterations'])} iterations)")
        uses = ("your curve_model and gauss_newton; their" if method == "gauss-newton"
                else f"your damping.GavinType{method[-1]} on the reference model; its")
        return Verdict(0.0, (
            f"{method} from (0, 0, 0) ends at params {fmt(got['params'])} with chi2 {fmt(got['final_chi2'])} "
            f"after {int(got['iterations'])} iterations; the reference ends at {fmt(want['params'])} with chi2 "
            f"{fmt(want['final_chi2'])} after {int(want['iterations'])} (rtol 1e-6). This run uses {uses} "
            "unit checks say which part differs"))

    return judge


# ---------------------------------------------------------------- registry


def _check(exercise, title, points, calls, judge, **kwargs):
    return Check(f"{exercise}: {title}", exercise, points, calls, judge, **kwargs)


def _mk_type(kind):
    cls = f"GavinType{kind}"
    ex = f"damping.{cls}"
    custom = {"lambda_0": 0.3} if kind == 1 else {"tau": 0.5}
    checks = [
        _check(ex, "initial_state", 1, _initial_calls(cls, custom),
               values(("lam", "nu"), LAM_RTOL, LAM_ATOL, _initial_mistakes(kind),
                      "type 1: lambda_0 as given" if kind == 1 else "lambda_0 = tau max diag(H), nu = 2")),
        _check(ex, "damping_diagonal", 2 if kind == 1 else 1, _diagonal_calls(cls),
               values(("value",), 1e-12, 0.0, _diagonal_mistakes(kind),
                      "d = lambda diag(H)" if kind == 1 else "d = lambda (1, ..., 1)", labels={"value": "d"})),
        _check(ex, "gain_denominator", 2 if kind == 1 else 1, _gain_calls(cls, kind),
               values(("value",), 1e-9, 1e-12, _gain_mistakes(kind),
                      "Gavin eq. 16: h^T (lambda diag(H) h - b)" if kind == 1 else "Gavin eq. 15: h^T (lambda h - b)",
                      labels={"value": "denominator"}, scalar=True)),
    ]
    if kind == 2:
        checks.append(_check(ex, "step_scale", 2, _alpha_calls,
                             values(("value",), 1e-9, 0.0, _alpha_mistakes,
                                    "alpha = g^T h / ((chi2(p+h) - chi2(p)) / 2 + 2 g^T h), g = -b, at least 0.1",
                                    labels={"value": "alpha"}, scalar=True)))
    update_hint = {
        1: "accepted: max(lambda / 9, 1e-7); rejected: min(lambda * 11, 1e7)",
        2: "accepted: max(lambda / (1 + alpha), 1e-7); rejected: lambda + |dchi2| / (2 alpha)",
        3: "accepted: lambda max(1/3, 1 - (2 rho - 1)^3), nu = 2; rejected: lambda nu, nu = 2 nu",
    }[kind]
    judge = values(("lam", "nu"), LAM_RTOL, LAM_ATOL, _update_mistakes(kind), update_hint)
    if kind == 1:
        checks += [
            _check(ex, "update (accepted step)", 1, _update_calls(cls, [((0.05,), 0.7, True), ((2.0,), 0.3, True)]), judge),
            _check(ex, "update (rejected step)", 1, _update_calls(cls, [((0.05,), -0.4, False), ((3.0,), 0.05, False)]), judge),
            _check(ex, "update (lambda clamped to [1e-7, 1e7])", 1,
                   _update_calls(cls, [((5e-7,), 0.9, True), ((2e6,), -1.0, False)]), judge),
        ]
    elif kind == 2:
        checks += [
            _check(ex, "update (accepted step)", 1, _update_calls(cls, [
                ((0.5,), 0.6, True, 0.4, -3.0), ((1.5e-7,), 0.9, True, 1.0, -2.0)]), judge),
            _check(ex, "update (rejected step)", 1, _update_calls(cls, [
                ((0.5,), -0.3, False, 0.25, 3.0), ((2.0,), 0.05, False, 0.3, -0.2)]), judge),
        ]
    else:
        checks += [
            _check(ex, "update (accepted step, nu reset)", 2, _update_calls(cls, [
                ((0.4, 8.0), 0.5, True), ((0.4, 4.0), 0.95, True), ((0.4, 16.0), 0.3, True)]), judge),
            _check(ex, "update (rejected step, nu doubled)", 1, _update_calls(cls, [
                ((0.4, 4.0), -0.2, False), ((0.1, 2.0), 0.05, False)]), judge),
        ]
    return checks


CHECKS = [
    _check(CURVE, "shapes", 1, _curve_calls, _judge_shapes),
    _check(CURVE, "r values", 3, _curve_calls,
           values(("r",), 1e-8, 1e-10, _r_mistakes, "check y_hat = exp(a x^2 + b x + c) and r = y_hat - y")),
    _check(CURVE, "J values", 3, _curve_calls, _judge_jacobian),
    _check(CURVE, "J vs finite differences of r", 3, _fd_calls, _judge_finite_differences),
    _check(NORMAL, "unit weights", 1, _normal_calls("unit"),
           values(("H", "b"), 1e-9, 1e-9, _normal_mistakes, {"H": "H = J^T W J", "b": "b = J^T W r"})),
    _check(NORMAL, "non-uniform weights", 3, _normal_calls("weighted"),
           values(("H", "b"), 1e-9, 1e-9, _normal_mistakes, {"H": "H = J^T W J", "b": "b = J^T W r"})),
    _check(STEP, "undamped step", 2, _step_calls(False),
           values(("value",), 1e-8, 1e-10, _step_mistakes, "h solves H h = -b", labels={"value": "h"},
                  errors={"LinAlgError": "H given here is symmetric positive definite"})),
    _check(STEP, "damped step", 2, _step_calls(True),
           values(("value",), 1e-8, 1e-10, _step_mistakes, "h solves (H + diag(damping)) h = -b",
                  labels={"value": "h"}, errors={"LinAlgError": (
                      "H + diag(damping) is symmetric positive definite here; H + damping (a vector) "
                      "adds it to every row: use H + np.diag(damping)")})),
    *_mk_type(1),
    *_mk_type(2),
    *_mk_type(3),
    *(_check(END, method, 2, _end_calls(method), _judge_end(method))
      for method in ("gauss-newton", "lm-type1", "lm-type2", "lm-type3")),
]
