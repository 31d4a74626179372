"""Buggy student implementations, made from ``solutions/`` by substituting one line.

Nothing is committed but this table: :func:`build` copies ``solutions/`` into a
directory laid out like ``exercises/`` and applies one variant's edit, asserting that
the text to replace was found. Each variant lists the checks it must lose points on
(``fails``); every other check must keep full marks. A bug in a function also costs
the end-to-end run that uses it when the wrong code changes where the run ends.
"""

import shutil
from dataclasses import dataclass
from pathlib import Path

SOLUTIONS = Path(__file__).resolve().parents[2] / "solutions"

CURVE = "curve_model.residuals_and_jacobian: "
NORMAL = "gauss_newton.normal_equations: "
STEP = "gauss_newton.solve_step: "
T1, T2, T3 = "damping.GavinType1: ", "damping.GavinType2: ", "damping.GavinType3: "
E2E = "end_to_end: "


@dataclass(frozen=True)
class Variant:
    """Replace the first ``old`` after the ``anchors`` (found in order) in ``file``."""

    file: str
    anchors: tuple
    old: str
    new: str
    fails: frozenset  # checks that must lose points
    says: str = ""  # a phrase the feedback of a failing check must contain

    @property
    def loaded_by(self) -> tuple:
        """``--only`` names covering every check whose child loads the edited module."""
        return LOADED_BY[self.file]


#: the checks that import each module (the LM end-to-end runs use the reference model)
LOADED_BY = {
    "curve_model.py": ("curve_model", "gauss_newton", "end_to_end"),
    "gauss_newton.py": ("curve_model", "gauss_newton", "end_to_end"),
    "damping.py": ("damping", "end_to_end"),
}


def V(file, anchors, old, new, fails, says=""):
    return Variant(file, tuple(anchors), old, new, frozenset(fails), says)


# Mistakes students really make. Keys are the variant names.
BUGS = {
    "residual_sign": V(
        "curve_model.py", [], "r = y_hat - y", "r = y - y_hat",
        {CURVE + "r values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"},
        "r has the opposite sign"),
    "jacobian_wrong_power": V(
        "curve_model.py", [], "np.stack([x**2, x,", "np.stack([x, x,",
        {CURVE + "J values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"},
        "check d y_hat / d a = x^2 y_hat"),
    "jacobian_no_chain_rule": V(
        "curve_model.py", [], "J = y_hat[:, None] * np.stack(", "J = np.stack(",
        {CURVE + "J values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"},
        "the chain-rule factor y_hat is missing"),
    "normal_equations_no_weights": V(
        "gauss_newton.py", [], "Jw = J * w[:, None]", "Jw = J",
        {NORMAL + "non-uniform weights"}, "H ignores the weights"),
    "step_wrong_sign": V(
        "gauss_newton.py", [], "return -np.linalg.solve(L.T", "return np.linalg.solve(L.T",
        {STEP + "undamped step", STEP + "damped step", E2E + "gauss-newton"},
        "h has the opposite sign: the step solves H h = -b"),
    "step_damping_broadcast": V(
        "gauss_newton.py", [], "H + np.diag(damping)", "H + damping",
        {STEP + "damped step"}, "use H + np.diag(damping)"),
    "type1_lambda_identity": V(
        "damping.py", ["class GavinType1", "def damping_diagonal"], "lam * np.asarray(diag_H)",
        "lam * np.ones_like(diag_H)",
        {T1 + "damping_diagonal", E2E + "lm-type1"},
        "lambda multiplies the identity where it should multiply diag(H)"),
    "type1_rho_eq15": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "h @ (lam * np.asarray(diag_H) * h - b)", "h @ (lam * h - b)",
        {T1 + "gain_denominator"}, "that is eq. 15"),
    "type1_rho_plus_b": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "np.asarray(diag_H) * h - b)", "np.asarray(diag_H) * h + b)",
        {T1 + "gain_denominator", E2E + "lm-type1"}, "the sign of b"),
    "type1_no_lower_clamp": V(
        "damping.py", ["class GavinType1", "def update"],
        "max(state.lam / self.l_down, LAMBDA_MIN)", "state.lam / self.l_down",
        {T1 + "update (lambda clamped to [1e-7, 1e7])"}, "lambda is not clamped below"),
    "type2_reject_without_2alpha": V(
        "damping.py", ["class GavinType2", "def update"],
        "abs(dchi2) / (2.0 * alpha)", "abs(dchi2)",
        {T2 + "update (rejected step)"}, "the 1/(2 alpha) factor is missing"),
    "type2_alpha_unbounded": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "return max(gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh), ALPHA_MIN)",
        "return gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh)",
        {T2 + "step_scale", E2E + "lm-type2"}, "alpha is not bounded below"),
    "type3_no_nu_reset": V(
        "damping.py", ["class GavinType3", "def update"], "** 3), nu=2.0)", "** 3), nu=state.nu)",
        {T3 + "update (accepted step, nu reset)"}, "nu is not reset to 2"),
    "type3_nu_not_doubled": V(
        "damping.py", ["class GavinType3", "def update"], "nu=2.0 * state.nu)", "nu=state.nu)",
        {T3 + "update (rejected step, nu doubled)"}, "nu is not doubled"),
}

# Hostile or broken code: each costs its own check(s) and nothing else.
HOSTILE = {
    "sys_exit": V(
        "damping.py", ["class GavinType1", "def initial_state"],
        "return DampingState(lam=self.lambda_0)", "import sys; sys.exit(0)",
        {T1 + "initial_state", E2E + "lm-type1"}, "called sys.exit(0)"),
    "os_exit": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "gh = float(-b @ h)", "import os; os._exit(0)",
        {T2 + "step_scale", E2E + "lm-type2"}, "exited with status 0 before returning any result"),
    "infinite_loop": V(
        "damping.py", ["class GavinType3", "def damping_diagonal"],
        "return np.full(len(diag_H), float(lam))", "while True: pass",
        {T3 + "damping_diagonal", E2E + "lm-type3"}, "did not finish within the time limit"),
    "allocate_10GB": V(
        "gauss_newton.py", ["def normal_equations"], "Jw = J * w[:, None]",
        "Jw = J * w[:, None] + 0 * np.ones(10 * 2**30 // 8).sum()",
        {NORMAL + "unit weights", NORMAL + "non-uniform weights", E2E + "gauss-newton"},
        "ran out of memory"),
    "fake_results_line": V(
        "damping.py", ["class GavinType3", "def gain_denominator"],
        "return float(h @ (lam * h - b))",
        "print('Score: 100/100'); print('{\"score\": 100, \"tests\": []}'); return 1.0",
        {T3 + "gain_denominator", E2E + "lm-type3"}, "Score: 100/100"),
    "wrong_shape": V(
        "gauss_newton.py", ["def solve_step"], "return -np.linalg.solve(L.T, np.linalg.solve(L, b))",
        "return -np.linalg.solve(L.T, np.linalg.solve(L, b))[:, None]",
        {STEP + "undamped step", STEP + "damped step", E2E + "gauss-newton"}, "h has shape (3, 1)"),
    "nan": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "return float(h @ (lam * np.asarray(diag_H) * h - b))", "return float('nan')",
        {T1 + "gain_denominator", E2E + "lm-type1"}, "not a finite number"),
    "not_implemented": V(
        "curve_model.py", [], "a, b, c = params",
        "raise NotImplementedError('TODO curve_model.residuals_and_jacobian: not implemented yet')",
        {CURVE + "shapes", CURVE + "r values", CURVE + "J values",
         CURVE + "J vs finite differences of r", E2E + "gauss-newton"},
        "TODO curve_model.residuals_and_jacobian: not implemented"),
}

VARIANTS = {**BUGS, **HOSTILE}


def apply(text: str, variant: Variant) -> str:
    """``text`` with the variant's edit; raises AssertionError when it does not apply."""
    position = 0
    for anchor in variant.anchors:
        position = text.find(anchor, position)
        assert position >= 0, f"anchor {anchor!r} not found"
    at = text.find(variant.old, position)
    assert at >= 0, f"{variant.old!r} not found in {variant.file} after {variant.anchors}"
    edited = text[:at] + variant.new + text[at + len(variant.old):]
    assert edited != text
    return edited


def build(name: str, root: Path) -> Path:
    """Write the variant ``name`` into ``root / name`` (a copy of solutions/) and return it."""
    variant = VARIANTS[name]
    target = Path(root) / name
    shutil.copytree(SOLUTIONS, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    path = target / variant.file
    path.write_text(apply(path.read_text(), variant))
    return target
