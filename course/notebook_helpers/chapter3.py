"""Chapter 3's lesson: the figures of the dogleg's theory, and the tables of its experiments.

The theory is drawn on a two-parameter problem, Rosenbrock's function written as least squares,
``r(x) = (x_2 - x_1^2, 1 - x_1)`` (:func:`rosenbrock`), linearized at ``x_0 = (-0.5, 0.5)``: there the
model ``L(h) = F + g^T h + h^T H h / 2`` (``F = |r|^2 / 2``, ``g = J^T r``, ``H = J^T J``) is a
quadratic in the plane, and every step is a point of that plane.

``dogleg_path``: the model along steepest descent and the dogleg path against the exact
trust-region curve. ``dogleg_on_curve``, ``radius_per_attempt``, ``attempts_table``: the radius, the
step length and the gain ratio of a dogleg run. ``factorization_table``, ``rejection_demo``: the
experiments' tables.

The points the student computes (the Cauchy point, the dogleg steps) come from the
implementation's ``dogleg`` module: while it is a TODO the figures say so in one line and draw
the rest.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from course.app import compare, plot
from course.core import impl as impl_loader
from course.core.trace import RunResult
from course.notebook_helpers.common import reached, rejected, show_rejections

#: the point where the theory's figures linearize Rosenbrock's function: there the Gauss-Newton step
#: overshoots (F grows along it) and the Cauchy point and h_gn are 38 degrees apart
START = np.array([-0.5, 0.5])
#: the trust-region radii drawn in the figure of the dogleg path: one per case but Gauss-Newton
RADII = (0.5, 1.2, 1.9)


def rosenbrock(x) -> tuple[np.ndarray, np.ndarray]:
    """Residual r (2,) and Jacobian J (2, 2) of ``r(x) = (x_2 - x_1^2, 1 - x_1)`` at x (2,)."""
    x1, x2 = np.asarray(x, dtype=float)
    return np.array([x2 - x1**2, 1.0 - x1]), np.array([[-2.0 * x1, 1.0], [-1.0, 0.0]])


def model(x=START) -> tuple[float, np.ndarray, np.ndarray]:
    """``(F, g, H)`` of the quadratic model at x: ``F = |r|^2 / 2``, g = J^T r (2,), H = J^T J (2, 2)."""
    r, J = rosenbrock(x)
    return 0.5 * float(r @ r), J.T @ r, J.T @ J


def todo_note(exc: NotImplementedError, what: str) -> str:
    """The one line a cell prints for an unwritten exercise: ``not written yet: TODO m.f (your m.py): what``."""
    todo = str(exc).strip().removesuffix(": not implemented yet") or "TODO (an unwritten exercise)"
    module = todo.removeprefix("TODO ").split(".")[0]
    return f"not written yet: {todo} (your {module}.py): {what}"


def trust_region_step(g, H, radius) -> np.ndarray:
    """The exact minimizer of the model within ``|h| <= radius``: ``h(lambda) = -(H + lambda I)^{-1} g``
    with the lambda >= 0 that puts it on the boundary (bisection in log lambda), or the Gauss-Newton
    step when that lies inside."""
    h_gn = np.linalg.solve(H, -g)
    if np.linalg.norm(h_gn) <= radius:
        return h_gn
    lo, hi = -12.0, 12.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if np.linalg.norm(np.linalg.solve(H + 10.0**mid * np.eye(len(g)), -g)) > radius:
            lo = mid
        else:
            hi = mid
    return np.linalg.solve(H + 10.0**hi * np.eye(len(g)), -g)


def _dogleg_points(impl, g, H, h_gn, radii):
    """``(a, alpha, [(radius, h, case)], note)`` from ``impl``'s dogleg; Nones and the TODO line while
    it is not written."""
    pieces = impl_loader.load(impl).module("dogleg")
    try:
        a, alpha = pieces.cauchy_point(g, H @ g)
    except NotImplementedError as exc:
        return None, None, [], todo_note(exc, "the figure shows the model without the Cauchy point and the path")
    a = np.asarray(a, dtype=float)
    steps = []
    try:
        for radius in radii:
            h, _, case = pieces.dogleg_step(g, h_gn, float(alpha), radius)
            steps.append((radius, np.asarray(h, dtype=float), case))
    except NotImplementedError as exc:
        return a, float(alpha), [], todo_note(exc, "the figure shows the path without your dogleg steps")
    return a, float(alpha), steps, ""


def dogleg_path(impl="solutions", x=START, radii: Sequence[float] = RADII):
    """Two panels at ``x`` on Rosenbrock's function.

    Left: along steepest descent ``h = -alpha g``, the model ``L(-alpha g)`` (a parabola in alpha)
    and the true ``F(x - alpha g)``, with the implementation's Cauchy point.
    Right: contours of the model in the plane of h; the exact trust-region curve
    ``h(lambda) = -(H + lambda I)^{-1} g`` (lambda from infinity to 0: from the origin along -g to
    h_gn); the dogleg path ``0 -> a -> h_gn``; for each radius in ``radii`` its circle, the
    implementation's dogleg step (a dot) and the exact trust-region step (a cross).

    Prints the lengths it draws (and, while ``dogleg`` is a TODO, one line naming it)."""
    F, g, H = model(x)
    h_gn = np.linalg.solve(H, -g)
    a, alpha, steps, note = _dogleg_points(impl, g, H, h_gn, radii)
    if note:
        print(note)
    fig = plot.figure(14.0, 5.5)
    left, right = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.0, 1.4]})

    # left: the model and the function along steepest descent
    gHg = float(g @ H @ g)
    top = 3.0 * (alpha if alpha else float(g @ g) / gHg)
    t = np.linspace(0.0, top, 200)
    left.plot(t, F - t * float(g @ g) + 0.5 * t**2 * gHg, label="model L(-alpha g)")
    left.plot(t, [0.5 * float(np.sum(rosenbrock(x - s * g)[0] ** 2)) for s in t], "--",
              label="F(x - alpha g), the true cost")
    if alpha:
        left.plot([alpha], [F - alpha * float(g @ g) + 0.5 * alpha**2 * gHg], "o", color="C3",
                  label=f"your Cauchy point: alpha = {alpha:.4g}")
    left.set_xlabel("alpha (step length along -g)")
    left.set_ylabel("cost")
    left.set_title("along steepest descent the model is a parabola in alpha")
    left.legend(fontsize=8)

    # right: the plane of h
    lams = np.logspace(4, -6, 400)
    curve = np.array([np.linalg.solve(H + lam * np.eye(2), -g) for lam in lams])
    points = [np.zeros(2), h_gn, curve[0]] + ([a] if a is not None else [])
    box = np.array(points)
    lo, hi = box.min(axis=0) - 1.0, box.max(axis=0) + 1.0
    u, v = np.meshgrid(np.linspace(lo[0], hi[0], 200), np.linspace(lo[1], hi[1], 200))
    hs = np.stack([u, v], axis=-1)
    L = F + hs @ g + 0.5 * np.einsum("...i,ij,...j->...", hs, H, hs)
    right.contour(u, v, L, levels=np.quantile(L, np.linspace(0.0, 0.6, 14) ** 2), colors="0.75", linewidths=0.6)
    right.plot(curve[:, 0], curve[:, 1], color="C0", label="exact trust-region steps h(lambda) (LM)")
    right.plot([0.0], [0.0], "k+", markersize=10)
    right.plot([h_gn[0]], [h_gn[1]], "s", color="C2", label=f"Gauss-Newton step, |h_gn| = {np.linalg.norm(h_gn):.3g}")
    if a is not None:
        right.plot([0.0, a[0], h_gn[0]], [0.0, a[1], h_gn[1]], color="C3", linewidth=2,
                   label=f"dogleg path 0 -> a -> h_gn, |a| = {np.linalg.norm(a):.3g}")
    angle = np.linspace(0.0, 2.0 * np.pi, 200)
    for k, radius in enumerate(radii):
        right.plot(radius * np.cos(angle), radius * np.sin(angle), ":", color="0.4", linewidth=0.8)
        exact = trust_region_step(g, H, radius)
        right.plot([exact[0]], [exact[1]], "x", color="C0", markersize=9,
                   label="exact step on each circle" if k == 0 else None)
    for k, (radius, h, case) in enumerate(steps):
        right.plot([h[0]], [h[1]], "o", color="C3", markersize=6,
                   label="your dogleg step on each circle" if k == 0 else None)
        right.annotate(f"radius {radius:g}: {case}", h, textcoords="offset points", xytext=(6, -12), fontsize=8)
    right.set_xlim(lo[0], hi[0])
    right.set_ylim(lo[1], hi[1])
    right.set_aspect("equal", adjustable="box")
    right.set_xlabel("h_1")
    right.set_ylabel("h_2")
    right.set_title("the dogleg path follows the trust-region curve")
    right.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.suptitle(f"Rosenbrock's function as least squares, linearized at x = ({x[0]:g}, {x[1]:g})")
    print(f"at x = ({x[0]:g}, {x[1]:g}): F = {F:.4g}, |g| = {np.linalg.norm(g):.4g}, "
          f"|h_gn| = {np.linalg.norm(h_gn):.4g}" + (f", |a| = {np.linalg.norm(a):.4g}" if a is not None else ""))
    F_gn = 0.5 * float(np.sum(rosenbrock(x + h_gn)[0] ** 2))
    print(f"the full Gauss-Newton step: F(x + h_gn) = {F_gn:.4g} "
          "(> F: the step is rejected; the model holds only near x)")
    for radius, h, case in steps:
        exact = trust_region_step(g, H, radius)
        print(f"radius {radius:g}: your dogleg step is {case}, |h| = {np.linalg.norm(h):.4g}, "
              f"{np.linalg.norm(h - exact):.3g} from the exact trust-region step")
    return fig


def dogleg_on_curve(impl="solutions") -> RunResult | None:
    """Our dogleg on chapter 1's curve (seed 0, start (0, 0, 0)); None, after one line naming the TODO,
    while the implementation's ``dogleg`` (or chapter 1) is not written."""
    (run,) = compare.run_curve(impl=impl, methods=["dogleg"], backends=["ours"], unimplemented="row")
    if run.not_run:
        print(f"not written yet: {run.not_run.removeprefix('not implemented: ')} (the figure of the radius needs it)")
        return None
    return run


def radius_per_attempt(run: RunResult):
    """Two panels per step attempt of a dogleg ``run``: (top) the trust radius the attempt started
    from and the length of its step, rejected attempts marked x; (bottom) the gain ratio rho, with
    the thresholds 0.25 and 0.75 of the radius update and 0, below which the step is rejected."""
    trace = run.trace[1:]
    k = np.array([r.iteration for r in trace])
    radius = np.array([r.damping for r in trace])  # the radius each attempt used
    step = np.array([r.step_norm for r in trace])
    rho = np.array([r.rho for r in trace])
    bad = np.array([not r.accepted for r in trace])
    fig = plot.figure(8.0, 6.0)
    top, bottom = fig.subplots(2, 1, sharex=True)
    top.semilogy(k, radius, drawstyle="steps-mid", label="trust radius of the attempt")
    top.semilogy(k, step, ".-", label="|h|, the step taken")
    top.semilogy(k[bad], step[bad], "x", color="C3", markersize=9, label="rejected")
    top.set_ylabel("length")
    top.legend(fontsize=8)
    top.set_title(f"{run.backend} {run.method} on the curve: {run.iterations} attempts, {int(bad.sum())} rejected, "
                  f"{run.factorizations} factorizations")
    bottom.plot(k, np.clip(rho, -2.0, 1.5), "o-", markersize=4)
    bottom.plot(k[bad], np.clip(rho[bad], -2.0, 1.5), "x", color="C3", markersize=9)
    for level, style in ((0.75, "--"), (0.25, "--"), (0.0, "-")):
        bottom.axhline(level, color="grey", linewidth=0.7, linestyle=style)
    bottom.set_ylabel("rho (clipped to [-2, 1.5])")
    bottom.set_xlabel("step attempt")
    bottom.xaxis.get_major_locator().set_params(integer=True)
    return fig


def attempts_table(run: RunResult) -> str:
    """One line per step attempt of a dogleg ``run``: the radius it used, the length of its step and
    where that step lies (``inside``: the Gauss-Newton step, shorter than the radius; ``boundary``: a
    steepest-descent or dogleg step, of length the radius), rho, accepted, the running
    factorization count."""
    lines = [f"{'attempt':>7} {'radius':>10} {'|h|':>10} {'step':>8} {'rho':>10} {'accepted':>8} "
             f"{'factorizations':>14}"]
    for r in run.trace[1:]:
        where = "inside" if r.step_norm < r.damping * (1.0 - 1e-9) else "boundary"
        lines.append(f"{r.iteration:7d} {r.damping:10.4g} {r.step_norm:10.4g} {where:>8} {r.rho:10.3g} "
                     f"{str(r.accepted):>8} {r.factorizations:14d}")
    return "\n".join(lines)


def factorization_table(results: Mapping[str, Sequence[RunResult]],
                        methods: Sequence[str] = ("gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg")) -> str:
    """A markdown table, one row per dataset: for each of our ``methods`` ``factorizations / step
    attempts (rejected attempts)``, and a note where the run did not end at the Gauss-Newton minimum;
    ``-`` for a method that did not run (a TODO)."""
    rows = ["| dataset | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for name, runs in results.items():
        ours = {r.method: r for r in runs if r.backend == "ours" and not r.not_run}
        cells = []
        for m in methods:
            r = ours.get(m)
            if r is None:
                cells.append("-")
                continue
            at = reached(r, runs)
            note = "" if at == "yes" else f", {at}"
            cells.append(f"{r.factorizations} / {r.iterations} ({len(rejected(r))} rejected){note}")
        rows.append(f"| {name} | " + " | ".join(cells) + " |")
    return ("Our methods: factorizations / step attempts (rejected attempts); "
            "a note where the run did not end at the Gauss-Newton minimum.\n\n" + "\n".join(rows))


def rejection_demo(impl, load: Callable, names: Sequence[str] = ("mit", "intel-g2o", "curve")) -> None:
    """Our dogleg and LM type 1 on the first of ``names`` that is on this machine (``load(name)``, the
    curve always is): the trace rows around each rejection, then, per method, how many factorizations
    each retry after a rejection needed. One line naming the TODO while an exercise it needs is not written."""
    for name in names:
        if name == "curve":
            runs = compare.run_curve(impl=impl, methods=["lm-type1", "dogleg"], backends=["ours"],
                                     unimplemented="row")
            break
        g = load(name)
        if g is not None:
            runs = compare.run_posegraph(g, impl=impl, methods=["lm-type1", "dogleg"], backends=["ours"],
                                         unimplemented="row")
            break
    by_method = {r.method: r for r in runs}
    missing = [r for r in runs if r.not_run]
    if missing:
        print(f"{name}: " + "; ".join(f"ours {r.method}: {r.not_run}" for r in missing))
        return
    retries = {"dogleg": show_rejections(by_method["dogleg"], limit=40, name=name)}
    print()
    retries["lm-type1"] = show_rejections(by_method["lm-type1"], limit=12, name=name)
    print()
    for method, counts in retries.items():
        print(f"{method}: {len(counts)} retries after a rejection, new factorizations before each: "
              f"{sorted(set(counts))}")
