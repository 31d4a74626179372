"""The chapter-4 benchmark runs every back end from the same start and prints ratios over Ceres."""

import pytest

from course import benchmark_bal


def test_per_iteration_times_every_back_end_on_a_synthetic_problem():
    timings = benchmark_bal.per_iteration("bal-synthetic:4:30", repeats=1, iterations=3, scipy_evaluations=1)
    backends = [t.backend for t in timings]
    assert sorted(backends) == ["ceres", "gtsam", "ours", "scipy"]
    for t in timings:
        if t.skipped:
            assert "not installed" in t.skipped
            continue
        assert t.seconds_per_iteration > 0
        assert t.result.final_chi2 < t.result.initial_chi2


def test_main_prints_the_ratio_column_and_skips_the_minimum_it_does_not_know():
    lines = []
    benchmark_bal.main(names=("bal-synthetic:4:30",), repeats=1, out=lines.append)
    assert any("/ ceres" in line for line in lines)
    assert any(line.startswith("ours ") for line in lines)


def test_a_missing_problem_is_one_line(tmp_path):
    lines = []
    benchmark_bal.main(names=(str(tmp_path / "missing.txt"),), repeats=1, out=lines.append)
    assert len(lines) == 1 and "skipped" in lines[0]


@pytest.mark.slow
def test_ladybug_time_to_solution_reaches_the_minimum(data_folder):
    seconds, iteration, cost = benchmark_bal.time_to_solution("ladybug-49", repeats=1)
    assert seconds is not None and iteration <= 100
    assert cost <= benchmark_bal.MINIMA["ladybug-49"] * (1 + benchmark_bal.TOLERANCE)
