"""Checks of ``parallel_assembly``: the chunk bounds, and the parallel assembly of the block
normal equations graded alone.

``chunk_bounds`` is judged by its properties (contiguous, covering every observation, as
many non-empty chunks as asked or one per observation, sizes within one of each other), so
any balanced chunking earns full marks. ``normal_equations_parallel`` runs in the child with
a stand-in ``kernel`` (``autograder.tasks.parallel_assembly.BlockKernel``) that sums per-observation blocks
the reference computed: the grade does not depend on the student's
``bundle_adjustment.normal_equations``. Its outputs must equal the serial assembly (the
blocks summed over all observations) to rtol 1e-12 (atol 1e-14 times the largest entry);
the kernel waits longer on earlier chunks, so a result collected in completion order shows.
The threads check asks that chunks overlap in time (2 to ``workers`` kernel calls at once)
and, with one worker, that they do not; speed is never judged here (see
``python -m course benchmark``).

Public inputs: the observation pattern of the bundle-adjustment checks' small problem (4
cameras, 12 points, 38 observations, shuffled) with Jacobian and residual entries that are
multiples of 1/2, so that every sum is exact in any order; chunk counts that do not divide
K, more chunks than observations, one worker and the default (one chunk per worker); and one
observation on two workers, and none at all (K = 0: zero blocks, W of shape (0, 9, 3)).
Hidden inputs: the same from the hidden seed's problem, other entries and chunk counts.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.bundle_adjustment import problem
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("parallel_assembly",)
#: the other exercise files its checks import (graded with a stand-in kernel)
USES = ("bundle_adjustment",)
BOUNDS = "parallel_assembly.chunk_bounds"
PARALLEL = "parallel_assembly.normal_equations_parallel"
TASK = "@autograder.tasks.parallel_assembly:parallel_normal_equations"

RTOL, ATOL = 1e-12, 1e-14  # atol relative to the output's largest reference entry (at least 1)

# ---------------------------------------------------------------- inputs


def _bounds_calls(seed=None):
    if seed is None:
        cases = [(10, 4), (38, 5), (7, 7), (5, 9), (12, 1), (1, 3), (0, 2), (100, 8)]
    else:
        rng = np.random.default_rng([seed, 401])
        cases = []
        for low, high in ((10, 60), (60, 400)):  # a remainder that is not zero
            while True:
                K, n = int(rng.integers(low, high)), int(rng.integers(3, 12))
                if K % n:
                    break
            cases.append((K, n))
        K = int(rng.integers(2, 9))
        cases += [(K, K + int(rng.integers(1, 6))), (K, K), (int(rng.integers(20, 90)), 1),
                  (1, int(rng.integers(2, 6))), (0, int(rng.integers(1, 4))),
                  (int(rng.integers(200, 999)), int(rng.integers(2, 17)))]
    calls = []
    for K, n in cases:
        note = "K = 0: no chunk" if K == 0 else (
            "more chunks than observations" if n > K else (f"K = {K} is not a multiple of {n}" if K % n else ""))
        where = f"for num_observations = {K}, chunks = {n}" + (f" ({note})" if note else "")
        calls.append(Call(f"parallel_assembly:{BOUNDS.split('.')[1]}", (K, n), where=where))
    return calls


@cache
def assembly_inputs(seed=None):
    """``(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points)``: the pattern of
    ``bundle_adjustment.problem(seed)`` with entries that are multiples of 1/2 (exact sums); the
    rows of r are unique (the stand-in kernel finds a chunk's observations by them)."""
    g = problem(seed)
    ci, pi = g["camera_index"], g["point_index"]
    K = len(ci)
    rng = np.random.default_rng(401 if seed is None else [seed, 403])
    while True:
        r = rng.integers(-128, 129, (K, 2)) / 2.0
        if len({row.tobytes() for row in r}) == K:
            break
    J_cam = rng.integers(-8, 9, (K, 2, 9)) / 2.0
    J_point = rng.integers(-8, 9, (K, 2, 3)) / 2.0
    return r, J_cam, J_point, ci, pi, len(g["cameras"]), len(g["points"])


@cache
def edge_inputs(seed=None, K=1):
    """The inputs of one observation (camera 1 of 2 sees point 2 of 3: the others see or are seen by nothing)
    or of none (``K = 0``), entries multiples of 1/2."""
    rng = np.random.default_rng(409 if seed is None else [seed, 409])
    r = rng.integers(-128, 129, (K, 2)) / 2.0
    J_cam, J_point = rng.integers(-8, 9, (K, 2, 9)) / 2.0, rng.integers(-8, 9, (K, 2, 3)) / 2.0
    index = np.ones(K, dtype=np.int64)
    return r, J_cam, J_point, index, 2 * index, 2, 3


@cache
def blocks(seed=None, K=None) -> dict:
    """The reference's per-observation blocks of ``assembly_inputs(seed)`` (``K``: of ``edge_inputs(seed,
    K)``) (instructor side: inside a calls builder): ``normal_equations`` with every observation its own
    camera and point."""
    from autograder import reference

    r, J_cam, J_point, _, _, _, _ = assembly_inputs(seed) if K is None else edge_inputs(seed, K)
    K = len(r)
    if K == 0:
        return {"U": np.zeros((0, 9, 9)), "V": np.zeros((0, 3, 3)), "W": np.zeros((0, 9, 3)),
                "g_cam": np.zeros((0, 9)), "g_point": np.zeros((0, 3)), "chi2": np.zeros(0)}
    own = np.arange(K)
    normal = reference.solutions_module("bundle_adjustment").normal_equations
    U, V, W, g_cam, g_point, _ = normal(r, J_cam, J_point, own, own, K, K)
    return {"U": U, "V": V, "W": W, "g_cam": g_cam, "g_point": g_point, "chi2": np.sum(r * r, axis=1)}


def _where(K, C, P, workers, chunks, note=""):
    asked = "chunks=None (one per worker)" if chunks is None else f"chunks={chunks}"
    return (f"with workers={workers}, {asked}{f' ({note})' if note else ''}, on {K} observations of {C} cameras "
            f"and {P} points (entries multiples of 1/2: every sum is exact)")


def _parallel_call(seed, workers, chunks, note="", K=None):
    args = assembly_inputs(seed) if K is None else edge_inputs(seed, K)
    size, C, P = len(args[0]), args[5], args[6]
    return Call(TASK, (*args, blocks(seed, K)), {"workers": workers, "chunks": chunks}, returns="dict",
                where=_where(size, C, P, workers, chunks, note), label=PARALLEL)


def _value_cases(seed=None):
    K = len(assembly_inputs(seed)[0])
    if seed is None:
        picks = [(2, None), (2, 5), (1, 3), (3, K + 4), (4, 7)]
    else:
        rng = np.random.default_rng([seed, 405])
        remainders = [n for n in range(3, 10) if K % n]
        picks = [(int(rng.integers(2, 4)), None), (2, int(rng.choice(remainders))),
                 (1, int(rng.choice(remainders))), (int(rng.integers(2, 5)), K + int(rng.integers(1, 8))),
                 (int(rng.integers(3, 6)), int(rng.choice(remainders)))]
    out = []
    for workers, chunks in picks:
        n = workers if chunks is None else chunks
        note = ("more chunks than observations" if n > K else
                f"K = {K} is not a multiple of {n}" if K % n else "")
        if workers == 1:
            note = "one worker" + (f"; {note}" if note else "")
        out.append((workers, chunks, note))
    return out


def _value_calls(seed=None):
    """The cases of :func:`_value_cases`, then one observation on two workers and no observation at all."""
    return [_parallel_call(seed, workers, chunks, note) for workers, chunks, note in _value_cases(seed)] + [
        _parallel_call(seed, 2, None, "fewer observations than workers; camera 0 sees no point", K=1),
        _parallel_call(seed, 2, None, "no observation: no chunk", K=0)]


def _thread_calls(seed=None):
    rng = np.random.default_rng(407 if seed is None else [seed, 407])
    return [_parallel_call(seed, 2, 4), _parallel_call(seed, 3, int(rng.integers(5, 9))),
            _parallel_call(seed, 1, 3, "one worker")]


# ---------------------------------------------------------------- judges


def _judge_bounds(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    for index, (call, got, _) in enumerate(triples):
        K, n = call.args
        b = np.asarray(got["value"], dtype=float)
        for value, why in ctx.known(index).get("value", ()):
            if b.shape == np.shape(value) and np.array_equal(b, value):
                return Verdict(0.0, f"chunk_bounds returned {_short(b)} {call.where}: {why}")
        text = _bounds_problem(b, K, n)
        if text:
            return Verdict(0.0, f"chunk_bounds returned {_short(b)} {call.where}: {text}")
    return failure or Verdict(1.0, "ok")


def _short(b) -> str:
    values = [f"{v:g}" for v in np.ravel(b)[:12]]
    return "[" + ", ".join(values) + (", ...]" if np.size(b) > 12 else "]")


def _bounds_problem(b, K, asked) -> str:
    """What is wrong with bounds ``b`` of K observations in ``asked`` chunks ('' when nothing)."""
    chunks = min(asked, K)
    if b.ndim != 1:
        return f"expected a 1-D array of {chunks + 1} bounds, got shape {b.shape}"
    if not np.all(np.isfinite(b)) or not np.array_equal(b, np.round(b)):
        return "the bounds must be whole numbers (indices of observations)"
    if len(b) != chunks + 1:
        what = "one per observation: " if asked > K else ""
        return (f"{len(b) - 1} chunks, expected {chunks} ({what}n = min(chunks, num_observations) chunks, "
                f"{chunks + 1} bounds)")
    if b[0] != 0 or b[-1] != K:
        if b[-1] < K:
            return (f"the last chunk ends at {b[-1]:g}, so observations {b[-1]:g} to {K - 1} are in no chunk "
                    "(the remainder K mod n must go somewhere: some chunks get one more)")
        return f"the chunks must start at 0 and end at num_observations = {K}"
    sizes = np.diff(b)
    if not len(sizes):
        return ""
    if np.any(sizes <= 0):
        return "every chunk must hold at least one observation (increasing bounds)"
    if sizes.max() - sizes.min() > 1:
        return (f"chunk sizes from {sizes.min():g} to {sizes.max():g}: balance them (sizes within one of each "
                "other, K // n or K // n + 1), or one thread waits for the other")
    return ""


def _coverage(got) -> str:
    """The cause the stand-in kernel's record shows ('' when every observation went once)."""
    if got["missing"] > 0:
        return (f"{got['missing']:g} observation(s) went to no kernel call, the first is {got['first_missing']:g} "
                "(a chunk dropped? the last chunk must end at K)")
    if got["repeated"] > 0:
        return (f"observation {got['first_repeated']:g} and others went to two kernel calls ({got['repeated']:g} "
                "extra): chunks [lo, hi) must not overlap")
    return ""


def _reordered(got_W, want_W) -> bool:
    """True when W holds the reference's blocks, in another order."""
    got, want = np.asarray(got_W, float), np.asarray(want_W, float)
    if got.shape != want.shape or got.ndim != 3 or np.array_equal(got, want):
        return False
    a, b = got.reshape(len(got), -1), want.reshape(len(want), -1)
    return bool(np.array_equal(a[np.lexsort(a.T[::-1])], b[np.lexsort(b.T[::-1])]))


_LABELS = {"U": "U[{}]", "V": "V[{}]", "W": "W[{}]", "g_cam": "g_cam[{}]", "g_point": "g_point[{}]", "chi2": "chi2"}


def _values(names, cause):
    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        for index, (call, got, want) in enumerate(triples):
            known = ctx.known(index)
            hint = _coverage(got) or cause
            for name in names:
                if name == "W" and _reordered(got["W"], want["W"]):
                    return Verdict(0.0, f"W holds the right blocks in another order {call.where}: W stays in "
                                        "observation order, chunk i's blocks at rows b[i]:b[i+1] (take the results "
                                        "in the order the chunks were submitted, not as they complete)")
                tolerance = ATOL * max(1.0, float(np.max(np.abs(want[name]), initial=0.0)))
                text = compare(got[name], want[name], _LABELS[name], RTOL, tolerance, call.where,
                               known.get(name, ()), hint, scalar=name == "chi2")
                if text:
                    return Verdict(0.0, text)
        return failure or Verdict(1.0, "ok")

    return judge


def _judge_threads(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, _ in triples:
        workers = call.kwargs["workers"]
        most = int(got["most_at_once"])
        if workers == 1 and most > 1:
            return Verdict(0.0, f"{most} kernel calls ran at once {call.where}: with one worker, one chunk at a "
                                "time (ThreadPoolExecutor(max_workers=workers))")
        if workers > 1 and most < 2:
            return Verdict(0.0, f"the chunks ran one at a time {call.where} (never two kernel calls at once): "
                                "submit every chunk to a ThreadPoolExecutor(max_workers=workers) before waiting "
                                "for any result")
        if most > workers:
            return Verdict(0.0, f"{most} kernel calls ran at once {call.where}: at most workers={workers} "
                                "threads (ThreadPoolExecutor(max_workers=workers))")
    return Verdict(1.0, "ok")


CHECKS = [
    check(BOUNDS, "contiguous balanced chunks", 2, _bounds_calls, _judge_bounds),
    check(PARALLEL, "U, V and W as the serial assembly", 3, _value_calls,
          _values(("U", "V", "W"), "U and V are the sums of the chunks' partial blocks (every chunk added once), "
                                   "W the chunks' blocks in observation order"),
          exact_inputs=True),  # entries multiples of 1/2: every sum exact, in any order
    check(PARALLEL, "gradients and chi2 as the serial assembly", 2, _value_calls,
          _values(("g_cam", "g_point", "chi2"), "g_cam, g_point and chi2 are the sums of the chunks' partial sums "
                                                "(every chunk added once)"),
          exact_inputs=True),
    check(PARALLEL, "chunks run on several threads at once", 1, _thread_calls, _judge_threads),
]


def _assembly_edge(test):
    def holds(call):
        K = len(call.args[0])
        chunks = call.kwargs["workers"] if call.kwargs["chunks"] is None else call.kwargs["chunks"]
        return test(K, chunks, call.kwargs["workers"], call)
    return holds


_B_TARGET = f"parallel_assembly:{BOUNDS.split('.')[1]}"

EDGES = (
    Edge("chunk_bounds: no observations (K = 0: b = [0], no chunk)", _B_TARGET, lambda c: c.args[0] == 0),
    Edge("chunk_bounds: one observation (K = 1)", _B_TARGET, lambda c: c.args[0] == 1),
    Edge("chunk_bounds: more chunks than observations (one observation per chunk)", _B_TARGET,
         lambda c: c.args[1] > c.args[0] > 0),
    Edge("chunk_bounds: as many chunks as observations", _B_TARGET, lambda c: c.args[1] == c.args[0] > 1),
    Edge("chunk_bounds: one chunk", _B_TARGET, lambda c: c.args[1] == 1),
    Edge("normal_equations_parallel: more chunks than observations", TASK,
         _assembly_edge(lambda K, n, w, c: n > K > 1)),
    Edge("normal_equations_parallel: one worker", TASK, _assembly_edge(lambda K, n, w, c: w == 1)),
    Edge("normal_equations_parallel: one observation on two workers (one chunk; a camera and points seen by none)",
         TASK, _assembly_edge(lambda K, n, w, c: K == 1 and w == 2)),
    Edge("normal_equations_parallel: no observations (K = 0: zero blocks, W (0, 9, 3), chi2 0)", TASK,
         _assembly_edge(lambda K, n, w, c: K == 0)),
)
