"""Chapter 1 on its source's own data: the C++ course code's noise (libstdc++'s minstd_rand0 through
its normal_distribution) drawn in numpy, and the source's Levenberg-Marquardt (lm-source)."""

import math

import numpy as np
import pytest

from course.core import impl
from course.problems.curve.problem import CurveProblem, curve_chi2
from course.problems.curve.source_data import MINSTD_RANGE, MinstdRand0, PolarNormal, canonical, source_data
from course.solver import minimize
from course.solver.source_nielsen import SOURCE_TAU, SourceNielsen

#: the accepted chi2 the C++ run prints (cout's 6 significant digits), first line at (0, 0, 0)
CPP_ACCEPTED = ["36048.3", "30015.5", "13421.2", "7273.96", "269.255"]


def accepted(run):
    """chi2 at the start and after every accepted step, and lambda after each of those steps."""
    chi2 = [run.trace[0].chi2]
    lam_after = []
    for k, record in enumerate(run.trace[1:], start=1):
        if record.accepted:
            chi2.append(record.chi2)
            if k + 1 < len(run.trace):
                lam_after.append(run.trace[k + 1].damping)
    return chi2, lam_after


def test_minstd_rand0_and_generate_canonical():
    engine = MinstdRand0()
    assert [engine() for _ in range(3)] == [16807, 282475249, 1622650073]  # 16807^k mod 2^31 - 1
    engine = MinstdRand0()
    u = canonical(engine)
    assert u == ((16807 - 1) + (282475249 - 1) * float(MINSTD_RANGE)) / float(MINSTD_RANGE * MINSTD_RANGE)
    assert 0.0 <= u < 1.0


def test_the_polar_method_returns_y_then_the_saved_x():
    engine, noise = MinstdRand0(), PolarNormal()
    first, second = noise(engine), noise(engine)
    replay = MinstdRand0()
    while True:
        x, y = 2.0 * canonical(replay) - 1.0, 2.0 * canonical(replay) - 1.0
        s = x * x + y * y
        if 0.0 < s <= 1.0:
            break
    mult = math.sqrt(-2.0 * math.log(s) / s)
    assert (first, second) == (y * mult, x * mult)
    assert replay.state == engine.state  # the second call drew nothing


def test_the_source_data_give_the_cpp_runs_first_chi2():
    data = source_data()
    assert np.array_equal(data.x, np.arange(100) / 100.0)
    assert f"{curve_chi2(data, np.zeros(3)):g}" == "36048.3"
    assert abs(np.mean(data.y - np.exp(data.x**2 + 2 * data.x + 1))) < 0.3  # noise of unit variance


def test_lm_source_accepts_what_the_cpp_run_prints():
    run = minimize(CurveProblem(source_data()), "lm-source")
    chi2, _ = accepted(run)
    assert [f"{value:g}" for value in chi2[:len(CPP_ACCEPTED)]] == CPP_ACCEPTED
    assert f"{run.final_chi2:g}" == "91.3959"
    assert run.trace[0].damping == pytest.approx(1e-3)  # 1e-5 max diag H, H_cc = 100 at (0, 0, 0)


def test_without_the_cap_type_3_parts_from_the_source_after_the_fourth_step():
    type3 = impl.load("solutions").module("damping").STRATEGIES["lm-type3"]
    capped, _ = accepted(minimize(CurveProblem(source_data()), SourceNielsen(type3(tau=SOURCE_TAU))))
    chi2, lam_after = accepted(minimize(CurveProblem(source_data()), SourceNielsen(type3(tau=SOURCE_TAU), cap=None)))
    assert [f"{value:g}" for value in chi2[:4]] == CPP_ACCEPTED[:4]
    assert f"{chi2[4]:.1f}" == "284.4" and f"{capped[4]:.1f}" == "269.3"
    _, lam_capped = accepted(minimize(CurveProblem(source_data()), "lm-source"))
    # lambda after the third accepted step, printed beside the fourth chi2 (7273.96)
    assert f"{lam_after[2]:.2f}" == "1864.17" and f"{lam_capped[2]:.2f}" == "1242.76"


def test_compare_runs_the_source_data_by_name():
    from course.app import compare

    (run,) = compare.run("curve:source", impl="solutions", methods=["lm-source"], backends=["ours"])
    assert f"{run.initial_chi2:g}" == "36048.3" and f"{run.final_chi2:g}" == "91.3959"
    assert compare.find_runner("curve:source").kind == "curve"
