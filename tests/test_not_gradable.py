"""A reference that fails on one check's hidden inputs costs that check only: it is reported as not
gradable (0 of 0 points, for every student alike), loudly on stderr for the instructor, and every
other check is graded."""

import dataclasses

import numpy as np

from autograder import grade, report
from autograder.checks import all_checks


def test_a_reference_failing_on_one_hidden_input_costs_that_check_only(capsys):
    checks = [c for c in all_checks() if c.exercise == "marginalisation.marginalise"]
    broken = checks[0]

    def calls(seed=None):
        out = broken.calls(seed)
        if seed is None:
            return out
        call = out[0]
        return [dataclasses.replace(call, args=(call.args[0], call.args[1], np.array([0, 0])))] + out[1:]

    chosen = [dataclasses.replace(broken, calls=calls)] + checks[1:]
    results = grade.grade("solutions", checks=chosen, which="hidden", workers=1)
    assert [r.status for r in results] == ["not gradable"] + ["ok"] * (len(checks) - 1)
    lost = results[0]
    assert (lost.score, lost.max_score) == (0.0, 0.0) and "reference solution failed" in lost.message
    assert "duplicate indices" in lost.message
    assert all(r.full and r.max_score > 0 for r in results[1:])
    assert "NOT GRADABLE" in capsys.readouterr().err
    results_json = report.gradescope(results, 1.0)
    assert results_json["tests"][0]["max_score"] == 0.0 and "not gradable" in results_json["tests"][0]["output"]
