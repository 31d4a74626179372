"""The chapter-4 benchmark runs every back end from the same start and prints ratios over Ceres."""

from course.app import benchmark_bal
from course.backends.bal.common import unpack
from course.problems.bal.dataset import FRONT, cost, load_bal


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
    benchmark_bal.main(names=("bal-synthetic:4:30",), repeats=1, out=lines.append, sweep=((4, 30), (6, 50)))
    assert any("/ ceres" in line for line in lines)
    assert any(line.startswith("ours ") for line in lines)
    assert any("how the cost grows" in line for line in lines)
    assert any(line.startswith("bal-synthetic:6:50:0") for line in lines)


def test_a_missing_problem_is_one_line(tmp_path):
    lines = []
    benchmark_bal.main(names=(str(tmp_path / "missing.txt"),), repeats=1, out=lines.append, sweep=())
    assert len(lines) == 1 and "skipped" in lines[0]


def test_time_to_the_minimum_stops_each_back_end_at_its_first_iterate_within_tolerance():
    name = "bal-synthetic:4:30" + FRONT
    problem = load_bal(name)
    minimum, found_by, reaches = benchmark_bal.time_to_minimum(name, repeats=1)
    target = minimum * (1 + benchmark_bal.TOLERANCE)
    ran = [r for r in reaches if not r.skipped]
    assert [r.backend for r in ran][0] == "ours" and found_by.split()[0] in {r.backend for r in ran}
    for r in ran:
        assert r.iteration is not None and r.seconds > 0
        # our cost where the run stopped, and no earlier stop would have been there
        assert minimum <= r.cost <= target
        if r.backend == "ours":
            full = benchmark_bal._ours(problem, "solutions", r.iteration - 1, r.method)
            assert cost(problem, *unpack(problem, full.params)) > target


def test_a_peer_that_does_not_get_there_within_its_cap_is_a_row_saying_so():
    _, _, reaches = benchmark_bal.time_to_minimum("bal-synthetic:4:30" + FRONT, repeats=1, caps={"ceres": 1})
    ceres = next(r for r in reaches if r.backend == "ceres")
    if not ceres.skipped:
        assert ceres.iteration is None and ceres.seconds is None and ceres.cap == 1
    lines = []
    benchmark_bal.main(names=("bal-synthetic:4:30",), repeats=1, out=lines.append, sweep=())
    assert any(line.startswith("bal-synthetic:4:30:front") and "best known minimum" in line for line in lines)


def test_the_size_sweep_times_ours_and_ceres_per_size():
    rows = benchmark_bal.size_sweep(((4, 30), (6, 60)), repeats=1, iterations=2)
    assert [row.name for row in rows] == ["bal-synthetic:4:30:0", "bal-synthetic:6:60:0"]
    assert rows[0].observations < rows[1].observations
    for row in rows:
        assert row.ours > 0
        assert row.ceres is None or row.ratio == row.ours / row.ceres
    table = benchmark_bal.format_sweep(rows)
    assert "ours / ceres" in table and len(table.splitlines()) == 3
