"""The parallel assembly (chapter 4): the reference exercise module, the grader's stand-in kernel
and task, the known mistakes' formulas, and the measurement module (on small problems)."""

import threading
import time

import numpy as np
import pytest

from autograder.checks import parallel_assembly as checks
from autograder.tasks.common import OutputError
from autograder.tasks.parallel_assembly import BlockKernel, parallel_normal_equations
from course.app import parallel_speedup
from course.core import impl as impl_loader
from course.problems.bal.dataset import synthetic
from solutions import bundle_adjustment as ba
from solutions import parallel_assembly as pa

SOLUTIONS = impl_loader.load("solutions")


@pytest.fixture(scope="module")
def linearized():
    """``(r, J_cam, J_point, camera_index, point_index, C, P)`` of a small synthetic problem, and its
    serial normal equations."""
    p = synthetic(6, 150, seed=3)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(p.cameras, p.points, p.camera_index, p.point_index,
                                                                 p.observations)
    args = (r, J_cam, J_point, p.camera_index, p.point_index, p.num_cameras, p.num_points)
    return args, ba.normal_equations(*args)


def assert_same(got, want):
    for name, a, b in zip(("U", "V", "W", "g_cam", "g_point", "chi2"), got, want):
        scale = max(1.0, float(np.max(np.abs(b))))
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-13 * scale, err_msg=name)


# ------------------------------------------------------------------ chunk_bounds


@pytest.mark.parametrize("K, chunks, expected", [
    (10, 4, [0, 3, 6, 8, 10]), (38, 5, [0, 8, 16, 24, 31, 38]), (12, 1, [0, 12]), (5, 9, [0, 1, 2, 3, 4, 5]),
    (1, 3, [0, 1]), (0, 2, [0]), (7, 7, list(range(8))),
])
def test_chunk_bounds_examples(K, chunks, expected):
    b = pa.chunk_bounds(K, chunks)
    assert b.dtype.kind == "i" and b.tolist() == expected


def test_chunk_bounds_are_contiguous_balanced_and_never_empty():
    for K in range(60):
        for chunks in range(1, 70):
            b = pa.chunk_bounds(K, chunks)
            sizes = np.diff(b)
            assert b[0] == 0 and b[-1] == K and len(sizes) == min(chunks, K)
            assert np.all(sizes >= 1) and (K == 0 or sizes.max() - sizes.min() <= 1)


@pytest.mark.parametrize("K, chunks, error, name", [
    (10, 0, ValueError, "chunks"), (10, -2, ValueError, "chunks"), (10, 1.5, TypeError, "chunks"),
    (10, True, TypeError, "chunks"), (-1, 2, ValueError, "num_observations"), (2.0, 2, TypeError, "num_observations"),
])
def test_chunk_bounds_bad_arguments_name_the_argument(K, chunks, error, name):
    with pytest.raises(error, match=name):
        pa.chunk_bounds(K, chunks)


def test_numpy_integers_are_accepted():
    assert pa.chunk_bounds(np.int64(10), np.int32(4)).tolist() == [0, 3, 6, 8, 10]


# ------------------------------------------------------------------ normal_equations_parallel


@pytest.mark.parametrize("workers, chunks", [(1, None), (2, None), (2, 7), (3, 10_000), (4, 3), (1, 5)])
def test_parallel_equals_serial(linearized, workers, chunks):
    args, serial = linearized
    out = pa.normal_equations_parallel(*args, workers=workers, chunks=chunks)
    assert isinstance(out[5], float)
    assert_same(out, serial)


def test_the_default_kernel_is_the_implementations_normal_equations(linearized, monkeypatch):
    args, serial = linearized
    calls, serial_assembly = [], ba.normal_equations

    def counting(*chunk):
        calls.append(len(chunk[0]))
        return serial_assembly(*chunk)

    monkeypatch.setattr(ba, "normal_equations", counting)
    assert_same(pa.normal_equations_parallel(*args, workers=2, chunks=5), serial)
    assert sorted(calls) == sorted(np.diff(pa.chunk_bounds(len(args[0]), 5)).tolist())


def test_no_observations_gives_zero_blocks_and_no_kernel_call():
    def kernel(*_):
        raise AssertionError("no chunk, no call")

    U, V, W, g_cam, g_point, chi2 = pa.normal_equations_parallel(
        np.zeros((0, 2)), np.zeros((0, 2, 9)), np.zeros((0, 2, 3)), np.zeros(0, int), np.zeros(0, int), 3, 4,
        kernel=kernel)
    assert U.shape == (3, 9, 9) and V.shape == (4, 3, 3) and W.shape == (0, 9, 3)
    assert not U.any() and not V.any() and not g_cam.any() and not g_point.any() and chi2 == 0.0


@pytest.mark.parametrize("kwargs, error, name", [
    ({"workers": 0}, ValueError, "workers"), ({"workers": "2"}, TypeError, "workers"),
    ({"workers": 2.0}, TypeError, "workers"), ({"chunks": 0}, ValueError, "chunks"),
    ({"chunks": -3}, ValueError, "chunks"), ({"kernel": 5}, TypeError, "kernel"),
])
def test_bad_arguments_name_the_argument(linearized, kwargs, error, name):
    args, _ = linearized
    with pytest.raises(error, match=name):
        pa.normal_equations_parallel(*args, **kwargs)


def test_chunks_overlap_in_time_and_w_stays_in_order_when_chunks_finish_out_of_order(linearized):
    """A kernel slower on earlier chunks: they finish in reverse, yet W is in observation order."""
    args, serial = linearized
    K = len(args[0])
    lock, running, most, threads = threading.Lock(), [0], [0], set()

    def slow_first(r, *rest):
        first = int(np.flatnonzero(np.all(args[0] == r[0], axis=1))[0])
        with lock:
            running[0] += 1
            most[0] = max(most[0], running[0])
            threads.add(threading.get_ident())
        time.sleep(0.02 * (1 - first / K))
        with lock:
            running[0] -= 1
        return ba.normal_equations(r, *rest)

    assert_same(pa.normal_equations_parallel(*args, workers=3, chunks=6, kernel=slow_first), serial)
    assert most[0] == 3 and len(threads) == 3


# ------------------------------------------------------------------ the grader's stand-in kernel and task


@pytest.fixture(scope="module")
def grader_inputs():
    return checks.assembly_inputs(None), checks.blocks(None)


def test_the_task_with_the_reference_matches_the_serial_assembly(grader_inputs):
    args, blocks = grader_inputs
    serial = ba.normal_equations(*args)
    out = parallel_normal_equations(*args, blocks, impl=SOLUTIONS, workers=2, chunks=5)
    assert_same([out[name] for name in ("U", "V", "W", "g_cam", "g_point", "chi2")], serial)
    assert (out["calls"], out["threads"], out["most_at_once"], out["missing"], out["repeated"]) == (5, 2, 2, 0, 0)
    assert out["first_missing"] == out["first_repeated"] == -1
    # entries are multiples of 1/2: the parallel sums are exact, equal to the serial ones bit for bit
    np.testing.assert_array_equal(out["U"], serial[0])


def _kernel(grader_inputs, stagger=False):
    args, blocks = grader_inputs
    return BlockKernel(*args, blocks, stagger=stagger)


def test_the_stand_in_kernel_refuses_what_is_not_a_chunk(grader_inputs):
    (r, J_cam, J_point, ci, pi, C, P), _ = grader_inputs
    kernel = _kernel(grader_inputs)
    kernel(r[3:9], J_cam[3:9], J_point[3:9], ci[3:9], pi[3:9], C, P)
    with pytest.raises(ValueError, match="empty chunk"):
        kernel(r[3:3], J_cam[3:3], J_point[3:3], ci[3:3], pi[3:3], C, P)
    with pytest.raises(ValueError, match="J_cam of other observations"):
        kernel(r[3:9], J_cam[4:10], J_point[3:9], ci[3:9], pi[3:9], C, P)
    with pytest.raises(ValueError, match="not rows of r"):
        kernel(r[3:9] + 0.25, J_cam[3:9], J_point[3:9], ci[3:9], pi[3:9], C, P)
    with pytest.raises(ValueError, match="num_cameras"):
        kernel(r[3:9], J_cam[3:9], J_point[3:9], ci[3:9], pi[3:9], C + 1, P)
    assert kernel.calls == 1 and kernel.seen.sum() == 6


class _Implementation:
    """An implementation whose parallel_assembly is ``module``."""

    def __init__(self, module):
        self._module = module

    def module(self, name):
        assert name == "parallel_assembly"
        return self._module


def test_the_task_reports_dropped_and_repeated_observations_and_an_unused_kernel(grader_inputs):
    args, blocks = grader_inputs
    K = len(args[0])

    class Dropping:
        @staticmethod
        def normal_equations_parallel(r, J_cam, J_point, ci, pi, C, P, workers, chunks, kernel):
            head = kernel(r[:K - 3], J_cam[:K - 3], J_point[:K - 3], ci[:K - 3], pi[:K - 3], C, P)
            again = kernel(r[K - 5:], J_cam[K - 5:], J_point[K - 5:], ci[K - 5:], pi[K - 5:], C, P)
            return tuple(a + b if k != 2 else a for k, (a, b) in enumerate(zip(head, again)))

    class Ignoring:
        @staticmethod
        def normal_equations_parallel(r, J_cam, J_point, ci, pi, C, P, workers, chunks, kernel):
            return ba.normal_equations(r, J_cam, J_point, ci, pi, C, P)

    out = parallel_normal_equations(*args, blocks, impl=_Implementation(Dropping), workers=2, chunks=2,
                                    stagger=False)
    assert out["missing"] == 0 and out["repeated"] == 2 and out["first_repeated"] == K - 5
    with pytest.raises(OutputError, match="never called its kernel"):
        parallel_normal_equations(*args, blocks, impl=_Implementation(Ignoring), workers=2, chunks=2)


def test_the_known_mistakes_differ_from_the_reference_and_name_their_cause(grader_inputs):
    from autograder.feedback import fields_of
    from autograder.mistakes.parallel_assembly import MISTAKES
    from autograder.oracle import compute

    check = next(c for c in checks.CHECKS if c.name.endswith("U, V and W as the serial assembly"))
    expected = compute(check, "parallel_assembly")
    call = expected.calls[1]  # workers=2, chunks=5: 38 observations, 3 left over
    assert call.kwargs == {"workers": 2, "chunks": 5}
    want, _ = fields_of(expected.reference[1], call)
    known = MISTAKES[check.name](call, want)
    causes = {name: [why for _, why in pairs] for name, pairs in known.items()}
    assert any("dropped" in why for why in causes["U"]) and any("overlap" in why for why in causes["V"])
    assert any("last chunk's partial sum only" in why for why in causes["U"])
    assert any("completed" in why for why in causes["W"])
    for name, pairs in known.items():
        for value, _ in pairs:
            assert np.shape(value) != np.shape(want[name]) or not np.array_equal(value, want[name]), name


# ------------------------------------------------------------------ measurement


def test_time_assembly_checks_and_times_every_variant():
    timing = parallel_speedup.time_assembly("bal-synthetic:4:60:1", repeats=1, configs=((1, None), (2, 3)))
    assert timing.num_observations > 60 and timing.serial.seconds > 0
    assert set(timing.parallel) == {(1, None), (2, 3), ("processes", 2)}
    assert all(m.seconds > 0 and m.cores >= 0 for m in timing.parallel.values())
    assert set(parallel_speedup.time_assembly("bal-synthetic:4:60:1", repeats=1, configs=(), processes=0).parallel) \
        == set()
    assert timing.jacobians is not None and timing.jacobians.seconds > 0


def test_time_iterations_splits_an_attempt_into_its_pieces():
    run = parallel_speedup.time_iterations("bal-synthetic:4:60:1", "lm-type3", workers=(2,), attempts=2, repeats=1)
    assert set(run.per_attempt) == {"serial", 2} and run.per_attempt["serial"] > 0
    pieces = run.pieces["serial"]
    assert sum(pieces.values()) < run.per_attempt["serial"] and 0 < run.assembly_share < 1
    assert run.linearizations >= 1 and 0 < run.amdahl(2) < 1 / (1 - run.assembly_share)


@pytest.mark.slow
def test_the_section_prints_tables_and_says_what_cannot_run():
    lines = []
    parallel_speedup.section(repeats=1, out=lines.append, problems=("bal-synthetic:4:60:1", "no-such-problem"),
                             configs=((1, None), (2, None)), methods=("dogleg",),
                             iteration_problems=("bal-synthetic:4:60:1",), attempts=2, iteration_repeats=1)
    text = "\n".join(lines)
    assert "no-such-problem          skipped: unknown BAL problem" in text
    assert "2w" in text and "dogleg" in text and "sorted(list) (control)" in text and "load average" in text
    lines = []
    parallel_speedup.section(repeats=1, impl="exercises", out=lines.append, problems=("bal-synthetic:4:60:1",))
    assert "skipped: TODO bundle_adjustment." in "\n".join(lines)


def test_sorted_holds_the_gil_and_matmul_releases_it():
    items = np.random.default_rng(0).random(400_000).tolist()
    J = np.random.default_rng(1).normal(size=(400_000, 2, 9))  # about 0.1 s: longer than a time slice
    assert parallel_speedup.gil_held(lambda: sorted(items)) > 0.8
    assert parallel_speedup.gil_held(lambda: np.matmul(J.transpose(0, 2, 1), J)) < 0.5
