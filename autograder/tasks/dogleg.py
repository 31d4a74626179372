"""The dogleg step graded alone, and a dogleg run on the curve problem (``checks/dogleg.py``)."""

import numpy as np

from autograder.tasks.common import OutputError, encode_text, run_summary


def dogleg_step(g, h_gn, alpha, radius, impl):
    """``dogleg.dogleg_step``; the case comes back as ``case_text`` (character codes) and
    ``case_code`` (0, 1, 2 for gauss-newton, steepest-descent, dogleg; -1 otherwise)."""
    out = impl.module("dogleg").dogleg_step(np.array(g, dtype=float), np.array(h_gn, dtype=float),
                                            float(alpha), float(radius))
    if not isinstance(out, tuple) or len(out) != 3:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (h, predicted_decrease, case)")
    h, predicted, case = out
    cases = ("gauss-newton", "steepest-descent", "dogleg")
    text = case if isinstance(case, str) else repr(case)
    code = cases.index(case) if isinstance(case, str) and case in cases else -1
    return {"h": h, "predicted": predicted, "case_code": float(code),
            "case_text": encode_text(text)}


def minimize_curve_run(method, impl, num_points=100, seed=0):
    """``course.solver.minimize`` on the curve problem (noise ``seed``), every piece from
    ``impl``, as :func:`autograder.tasks.common.run_summary` (rejections, factorizations)."""
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import minimize

    problem = CurveProblem(generate(num_points=num_points, seed=seed), impl=impl)
    return run_summary(minimize(problem, method, impl=impl))
