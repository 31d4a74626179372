"""Chapter 1's lesson: the figures of the theory and the tables of the source's own run.

``model_and_trust_region``: chi2 along the Gauss-Newton step against the quadratic model, and the
damped step's length and gain ratio as lambda grows. ``damping_factors``: what each rule
multiplies lambda by, as a function of the gain ratio rho. ``accepted``, ``cpp_lines``: a run as the
C++ source prints it. ``constant_table``: the source's variant with one constant changed at a time.
"""

from __future__ import annotations

import numpy as np

from course.app import plot
from course.core import impl as impl_loader
from course.core.trace import RunResult
from course.problems.curve.problem import CurveData, CurveProblem
from course.solver import minimize
from course.solver.source_nielsen import SOURCE_CAP, SOURCE_OFFSET, SOURCE_TAU, SourceNielsen

#: what the C++ run prints (cout's six significant digits): the chi2 at the start and after the
#: first three accepted steps, and the last; the fifth line to one decimal (269.3)
CPP_PRINTED = ["36048.3", "30015.5", "13421.2", "7273.96"]
CPP_FIFTH, CPP_LAST = "269.3", "91.3959"


def matches_cpp(run: RunResult) -> bool:
    """Whether ``run`` prints what the C++ run prints, as far as :data:`CPP_PRINTED` says."""
    rows = [chi2 for chi2, _ in accepted(run)]
    return (len(rows) > 4 and [f"{v:g}" for v in rows[:4]] == CPP_PRINTED and f"{rows[4]:.1f}" == CPP_FIFTH
            and f"{run.final_chi2:g}" == CPP_LAST)


def model_and_trust_region(data: CurveData, impl="solutions"):
    """Two panels at the start ``data.start``: (left) chi2(p + t h_gn) against the Gauss-Newton
    model ``chi2 + 2 t b^T h + t^2 h^T H h`` for t in [0, 1]; (right) the length of the damped step
    ``(H + lambda I) h = -b`` and its gain ratio rho against lambda."""
    problem = CurveProblem(data, impl)
    p = np.asarray(data.start, dtype=float)
    lin = problem.linearize(p)
    h = problem.solve(lin, None)
    fig = plot.figure(11.0, 4.2)
    left, right = fig.subplots(1, 2)
    t = np.linspace(0.0, 1.0, 101)
    with np.errstate(over="ignore", invalid="ignore"):
        actual = np.array([problem.chi2(p + s * h) for s in t])
    model = lin.chi2 + 2.0 * t * float(lin.b @ h) + t**2 * float(h @ lin.matvec(h))
    left.semilogy(t, actual, label="chi2(p + t h_gn)")
    left.semilogy(t, np.maximum(model, 1e-3), "--", label="Gauss-Newton model (clipped at 1e-3)")
    left.set_xlabel("t (fraction of the Gauss-Newton step)")
    left.set_ylabel("chi2")
    left.set_title("the quadratic model holds only near p")
    left.legend()
    lams = np.logspace(-3, 7, 61)
    lengths, rhos = [], []
    for lam in lams:
        step = problem.solve(lin, np.full(3, lam))
        predicted = float(step @ (lam * step - lin.b))
        with np.errstate(over="ignore", invalid="ignore"):
            rhos.append((lin.chi2 - problem.chi2(p + step)) / predicted)
        lengths.append(float(np.linalg.norm(step)))
    right.loglog(lams, lengths, label="|h(lambda)|")
    right.set_xlabel("lambda")
    right.set_ylabel("|h|")
    twin = right.twinx()
    rho = np.array(rhos, dtype=float)
    twin.semilogx(lams, np.clip(np.where(np.isfinite(rho), rho, -1.0), -1.0, 1.2), "C1",
                  label="rho (clipped to [-1, 1.2])")
    twin.axhline(0.0, color="grey", linewidth=0.5)
    twin.set_ylabel("rho")
    right.set_title("lambda is a trust radius: |h| falls as lambda grows")
    lines = right.get_lines() + twin.get_lines()[:1]
    right.legend(lines, [line.get_label() for line in lines], loc="center left")
    return fig


def damping_factors(epsilon_4: float = 0.1):
    """lambda_new / lambda against rho for an accepted or rejected step: Gavin's type 1 (9 and 11),
    Nielsen's rule (type 3, first rejection nu = 2) and the source's capped Nielsen (accepts rho > 0)."""
    rho = np.linspace(-0.5, 1.0, 601)
    nielsen = np.maximum(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
    fig = plot.figure(7.5, 4.2)
    ax = fig.subplots()
    ax.semilogy(rho, np.where(rho > epsilon_4, 1.0 / 9.0, 11.0), label="type 1: / 9 accepted, x 11 rejected")
    ax.semilogy(rho, np.where(rho > epsilon_4, nielsen, 2.0),
                label="type 3 (Nielsen): max(1/3, 1 - (2 rho - 1)^3); x nu")
    ax.semilogy(rho, np.where(rho > 0.0, np.minimum(nielsen, SOURCE_CAP), 2.0), "--",
                label="the source: capped at 2/3, accepts rho > 0")
    ax.axvline(epsilon_4, color="grey", linewidth=0.5)
    ax.set_xlabel("gain ratio rho = actual / predicted decrease of chi2")
    ax.set_ylabel("lambda_new / lambda")
    ax.set_title("how far lambda moves after one step")
    ax.legend(fontsize=8)
    return fig


def accepted(run: RunResult) -> list:
    """``[(chi2, lambda)]``: the start and every accepted step, with the lambda the next step starts
    from (what the C++ source prints on one line)."""
    lines = [(run.trace[0].chi2, run.trace[0].damping)]
    for k, record in enumerate(run.trace[1:], start=1):
        if record.accepted:
            lam = run.trace[k + 1].damping if k + 1 < len(run.trace) else float("nan")
            lines.append((record.chi2, lam))
    return lines


def cpp_lines(run: RunResult, limit: int | None = None) -> str:
    """The run as the C++ source prints it: ``iter: k , chi= ... , Lambda= ...`` (6 digits)."""
    rows = accepted(run)[:limit]
    return "\n".join(f"iter: {k} , chi= {chi2:g} , Lambda= {lam:g}" if np.isfinite(lam) else
                     f"iter: {k} , chi= {chi2:g}  (the last step)" for k, (chi2, lam) in enumerate(rows))


def source_variant(impl="solutions", tau=SOURCE_TAU, threshold=0.0, cap: float | None = SOURCE_CAP,
                   offset=SOURCE_OFFSET) -> SourceNielsen:
    """The source's rule with ``impl``'s type 3, one constant changed if asked."""
    type3 = impl_loader.load(impl).module("damping").STRATEGIES["lm-type3"]
    return SourceNielsen(type3(tau=tau), threshold=threshold, cap=cap, offset=offset)


def constant_table(data: CurveData, impl="solutions") -> str:
    """The source's variant, then one constant at a time set back to Gavin's: attempts, accepted
    steps, the fifth chi2 printed, the final chi2 and whether every printed chi2 matches the C++ run's."""
    variants: dict[str, dict] = {
        "the source (tau 1e-5, rho > 0, cap 2/3)": {},
        "no cap": {"cap": None},
        "tau = 1e-2 (lm.m's lambda_0)": {"tau": 1e-2},
        "accept at rho > 0.1 (Gavin's eps_4)": {"threshold": 0.1},
        "no 1e-3 in the denominator": {"offset": 0.0},
        "Gavin's type 3 (all four)": {"cap": None, "tau": 1e-2, "threshold": 0.1, "offset": 0.0},
    }
    out = [f"{'variant':42} {'attempts':>8} {'accepted':>8} {'5th chi2':>9} {'final chi2':>11}  C++ printed"]
    for name, change in variants.items():
        run = minimize(CurveProblem(data, impl), source_variant(impl, **change), impl=impl)
        rows = accepted(run)
        same = matches_cpp(run)
        fifth = f"{rows[4][0]:.6g}" if len(rows) > 4 else "-"
        out.append(f"{name:42} {run.iterations:>8} {len(rows) - 1:>8} {fifth:>9} {run.final_chi2:>11.6g}  "
                   f"{'same' if same else 'differs'}")
    return "\n".join(out)
