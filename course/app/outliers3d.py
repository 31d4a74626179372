"""Chapter 6's outlier experiment: ``python -m course outliers3d GRAPH [--shares 0.1,0.2,0.5]``.

For each share, the graph's loop closures are replaced by random ones at that share (seeded,
``course.problems.posegraph3d.outliers``) and solved by least squares, a Cauchy kernel (scale
``sqrt(c2)``) and GNC (TLS and Geman-McClure), ours and GTSAM's (``GncGaussNewtonOptimizer``:
Gauss-Newton inside, its inner solves capped as ours, ``robust.INNER``), all from the chordal
start of the corrupted graph; and, as the bar GNC is held to, by least squares on
the corrupted graph with its wrong closures removed (they are known here: "oracle LS"). Each
row: the translation and rotation rmse against the truth (the gtsam wheel's for sphere2500;
elsewhere against our solution of the graph without outliers), the precision and recall of
the rejected edges as a detector of the wrong ones, the share of right loop closures kept,
outer and inner iterations, seconds.
"""

import functools

import numpy as np

from course.core.errors import SingularSystemError
from course.core.peers import PeerMissing
from course.problems.posegraph3d import dataset as datasets
from course.problems.posegraph3d import robust
from course.problems.posegraph3d.initialise import initialise
from course.problems.posegraph3d.outliers import odometry, with_wrong_loop_closures

#: least squares and Cauchy stop here: with wrong closures they need not converge, and each of their
#: iterations factors the fill-in the random closures cause
BASELINE_ITERATIONS = 30
#: the Cauchy kernel's scale: sqrt(c2), the same threshold as GNC's
CAUCHY = ("cauchy", float(np.sqrt(robust.C2_6DOF_99)))
HEADER = (f"{'share':>5} {'method':18} {'t rmse':>8} {'R rmse':>8} {'precision':>9} {'recall':>7} "
          f"{'right kept':>10} {'outer':>5} {'inner':>5} {'seconds':>8}")


def _row(share, method, t, R, kept, truth, outliers, right, outer, inner, seconds) -> dict:
    t_rmse, r_rmse = robust.errors_against(t, R, *truth)
    precision, recall = robust.precision_recall(kept, outliers)
    return {"share": share, "method": method, "t_rmse": t_rmse, "R_rmse": r_rmse, "precision": precision,
            "recall": recall, "right_kept": float(np.mean(kept[right])), "outer": outer, "inner": inner,
            "seconds": seconds}


def _without_outliers(graph, outliers, impl):
    """Least squares on ``graph`` without its wrong closures, as a run over all of its edges."""
    r = robust.least_squares(graph.with_edges(~outliers), impl)
    return robust.RobustRun("least squares, wrong closures removed", r.t, r.R, ~outliers, r.outer, r.inner,
                            r.seconds)


def run(name, shares=(0.1, 0.2, 0.5), seed=1, impl="solutions", peers=True, on_row=None) -> tuple:
    """``(rows, truth_label)``: one dict per (share, method); see the module docstring.
    ``on_row(row, truth_label)`` is called as each row is ready (a long run shows its progress)."""
    graph = datasets.load_dataset(name)
    truth, label = graph.ground_truth, "the truth"
    if truth is None:
        clean = robust.least_squares(graph, impl)
        truth, label = (clean.t, clean.R), "our solution without outliers"
    rows: list = []

    def add(row):
        rows.append(row)
        if on_row is not None:
            on_row(row, label)

    for share in [0.0, *shares]:
        corrupted = with_wrong_loop_closures(graph, share, seed)
        outliers = np.asarray(corrupted.outliers, dtype=bool)
        right = ~outliers & ~odometry(corrupted)
        methods = [("least squares", lambda g: robust.least_squares(g, impl, max_iterations=BASELINE_ITERATIONS))]
        if share > 0:
            # the best any method can do: least squares on the right edges alone (the wrong ones known)
            methods += [("oracle LS", functools.partial(_without_outliers, outliers=outliers, impl=impl))]
            methods += [("cauchy", lambda g: robust.least_squares(g, impl, loss=CAUCHY,
                                                                  max_iterations=BASELINE_ITERATIONS)),
                        ("GNC TLS", lambda g: robust.gnc(g, "tls", impl)),
                        ("GNC GM", lambda g: robust.gnc(g, "gm", impl))]
        for method, solve in methods:
            try:
                r = solve(corrupted)
            except SingularSystemError as exc:  # one method's failure is a row, not the end of the table
                add({"share": share, "method": f"ours {method}", "failed": str(exc)})
                continue
            add(_row(share, f"ours {method}", r.t, r.R, r.kept, truth, outliers, right, r.outer, r.inner,
                             r.seconds))
        if share > 0 and peers:
            try:
                from course.backends import registry

                registry.peer_solver("posegraph3d", "gtsam")
                from course.backends.posegraph3d.gtsam import solve_gnc
            except PeerMissing:
                continue
            start, seconds = initialise(corrupted, "chordal", impl)
            for surrogate in ("tls", "gm"):
                t, R, weights, gnc_seconds = solve_gnc(start, surrogate, known_inliers=odometry(corrupted),
                                                        inner_iterations=robust.INNER.max_iterations)
                add(_row(share, f"gtsam GNC {surrogate.upper()}", t, R, weights > 0.5, truth, outliers,
                                 right, 0, 0, seconds + gnc_seconds))
    return rows, label


def format_row(r) -> str:
    if "failed" in r:
        return f"{r['share']:5.0%} {r['method']:18} failed: {r['failed']}"
    return (f"{r['share']:5.0%} {r['method']:18} {r['t_rmse']:8.4f} {r['R_rmse']:8.5f} {r['precision']:9.3f} "
            f"{r['recall']:7.3f} {r['right_kept']:10.3f} {r['outer']:5d} {r['inner']:5d} {r['seconds']:8.2f}")


def main(name, shares=(0.1, 0.2, 0.5), seed=1, impl="solutions", out=print) -> list:
    """Print the table row by row as the runs end (a full run on sphere2500 takes tens of minutes)."""
    out(f"{name}: loop closures replaced by random ones (seed {seed}); every method from the chordal start of the "
        f"corrupted graph; threshold c2 = {robust.C2_6DOF_99:.2f} on e^T Omega e")
    printed: list = []

    def show(row, label):
        if not printed:
            out(f"errors against {label}")
            out(HEADER)
        printed.append(row)
        out(format_row(row))

    return run(name, shares, seed, impl, on_row=show)[0]
