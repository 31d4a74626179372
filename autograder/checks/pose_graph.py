"""Chapter 2 end to end: Gauss-Newton on a pose graph in the child with the student's own
loop pieces only (pose_graph_edge, pose_graph_assembly, sparse_solve), compared with
where the reference run ends.

Public inputs: a 40-pose Manhattan world (seed 2); hidden inputs: another seed.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Check, Verdict
from autograder.checks.common import failed
from autograder.feedback import call_fields, compare, fmt

MODULES = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve")
END = "pose_graph.end_to_end"
PIECES = "your pose_graph_edge, pose_graph_assembly and sparse_solve"


@cache
def _graph(seed=None):
    from course.problems.posegraph.dataset import manhattan

    noise = 2 if seed is None else int(np.random.default_rng([seed, 241]).integers(3, 1 << 30))
    g = manhattan(40, seed=noise)
    return {"poses": g.poses, "edges_i": g.edges_i, "edges_j": g.edges_j, "measurements": g.measurements,
            "information": g.information, "fixed": g.fixed, "name": g.name}


def _end_calls(seed=None):
    graph = _graph(seed)
    return [Call("@autograder.tasks.pose_graph:minimize_pose_graph", (graph, "gauss-newton"), {"vectorized": False},
                 returns="dict", label=f"minimize(pose graph, 'gauss-newton') with {PIECES}",
                 where=f"on {graph['name']} ({len(graph['poses'])} poses, {len(graph['edges_i'])} edges)")]


def _judge_end(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        if "SIGSEGV" in failure.message:
            failure.message += (": the sparse solver (qdldl) crashes when the matrix it is given is not the upper "
                                "triangle of a symmetric H; see the upper_triangle_csc and SparseCholeskySolver checks")
        return failure
    call, got, want = triples[0]
    text = compare(got["final_chi2"], want["final_chi2"], "final chi2", 1e-6, 0.0)
    moved = float(np.max(np.abs(got["params"] - want["params"]))) if got["params"].shape == want["params"].shape \
        else float("inf")
    if text is None:
        return Verdict(1.0, f"ok (chi2 {float(got['final_chi2']):.6g} after {int(got['iterations'])} iterations)")
    return Verdict(0.0, (
        f"Gauss-Newton {call.where} ends at chi2 {fmt(got['final_chi2'])} after {int(got['iterations'])} "
        f"iterations; the reference ends at {fmt(want['final_chi2'])} after {int(want['iterations'])} (rtol 1e-6; "
        f"poses differ by up to {moved:.3g}). This run uses {PIECES}: their unit checks point at the part that "
        "differs; if their unit checks pass, look for state kept between calls (e.g. on the class) or arrays "
        "modified in place"))


CHECKS = [Check(f"{END}: gauss-newton", END, 3, _end_calls, _judge_end)]
