"""Framework runs that a check asks the child to perform with the student's code.

A task is a function taking ``impl=`` (the loaded implementation) and returning a
dict of numbers or arrays. The parent calls the same function with ``solutions``
for the reference; the child calls it with the student's implementation (a call
target ``"@autograder.tasks:minimize_curve"``).
"""

import threading
from contextlib import contextmanager

import numpy as np


def minimize_curve(method, impl, num_points=100, seed=0):
    """``course.solver.minimize`` on the curve problem (noise ``seed``), every piece from ``impl``."""
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import minimize

    problem = CurveProblem(generate(num_points=num_points, seed=seed), impl=impl)
    result = minimize(problem, method, impl=impl)
    return {
        "params": np.asarray(result.params, float),
        "final_chi2": float(result.final_chi2),
        "iterations": float(result.iterations),
        "accepted": float(sum(1 for record in result.trace[1:] if record.accepted)),
    }


# ---------------------------------------------------------------- chapters 2 and 3
#
# The tasks below return only numbers and arrays (the child writes nothing else):
# a string such as the dogleg case comes back as its character codes. A task that
# instruments the implementation (a stand-in for a function, a counter around a
# library class) does so only when it is the only Python thread, i.e. in the child:
# the parent computes the reference outputs in worker threads that share modules.

#: why a minimizer stopped, as the code returned in ``stop``
STOP_REASONS = ("max_iterations", "gradient_tolerance", "cost_tolerance", "step_tolerance")


class OutputError(Exception):
    """The student's code returned something the framework cannot use (reported as is)."""


def _exclusive() -> bool:
    """True when no other Python thread runs (the child): module state may be patched."""
    return threading.active_count() == 1


def encode_text(text, limit=60) -> np.ndarray:
    """A string as float character codes (the child returns numbers only)."""
    return np.array([float(ord(c)) for c in str(text)[:limit]], dtype=float)


def decode_text(codes) -> str:
    return "".join(chr(int(c)) for c in np.asarray(codes, dtype=float).ravel() if 0 <= c < 0x110000)


def _stub_todo(call) -> str:
    """The NotImplementedError message of ``call()`` when it is an unwritten stub, else ''.

    Used when a constructor is a stub, to also name the stub of a method that could not
    be reached (so that every TODO is listed); any other outcome says nothing.
    """
    try:
        call()
    except NotImplementedError as exc:
        return str(exc)
    except Exception:  # noqa: BLE001 - a written method on a bare instance may fail anyhow
        return ""
    return ""


def _graph(graph: dict):
    from course.problems.posegraph.graph import PoseGraph

    return PoseGraph(graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"],
                     graph["information"], fixed=graph["fixed"], name=graph.get("name", "graph"))


def _summary(result) -> dict:
    """A run as numbers: where it ended, and how rejected steps were retried."""
    trace = result.trace
    rejected = [k for k in range(1, len(trace)) if not trace[k].accepted]
    refactorized = [k for k in rejected
                    if k + 1 < len(trace) and trace[k + 1].factorizations != trace[k].factorizations]
    trailing = 0
    for record in reversed(trace[1:]):
        if record.accepted:
            break
        trailing += 1
    reason = result.stop_reason
    return {
        "params": np.asarray(result.params, float).ravel(),
        "final_chi2": float(result.final_chi2),
        "iterations": float(result.iterations),
        "factorizations": float(result.factorizations),
        "rejected": float(len(rejected)),
        "refactorized_after_rejection": float(len(refactorized)),
        "trailing_rejections": float(trailing),
        "stop": float(STOP_REASONS.index(reason) if reason in STOP_REASONS else -1),
    }


# -- chapter 2: assembly graded alone


def assemble_with_reference_edges(poses, edges_i, edges_j, measurements, information, fixed,
                                  edge_blocks, impl):
    """``pose_graph_assembly.assemble_normal_equations`` with the edge function replaced.

    ``edge_blocks`` is ``(e, A, B)`` of every edge (M, 3), (M, 3, 3), (M, 3, 3), computed
    by the reference in the parent: in the child, ``pose_graph_edge.edge_error_and_jacobians``
    returns them for ``(poses[i], poses[j], measurements[k])``, so that the assembly is
    graded alone. Arguments that are not an edge of the graph raise a ValueError that
    says so (e.g. poses i and j swapped).
    """
    assembly = impl.module("pose_graph_assembly")
    edge_module = impl.module("pose_graph_edge")
    e_all, A_all, B_all = (np.asarray(v, dtype=float) for v in edge_blocks)
    table = {}
    for k, (i, j) in enumerate(zip(edges_i, edges_j)):
        key = tuple(float(v) for v in np.concatenate([poses[i], poses[j], measurements[k]]))
        table.setdefault(key, k)

    def edge_error_and_jacobians(x_i, x_j, z_ij):
        try:
            key = tuple(float(v) for v in np.concatenate(
                [np.asarray(v, dtype=float).reshape(3) for v in (x_i, x_j, z_ij)]))
        except (TypeError, ValueError):
            key = None
        if key not in table:
            raise ValueError(
                "pose_graph_edge.edge_error_and_jacobians was called with arguments that are not "
                "(poses[i], poses[j], measurements[k]) of any edge k from i to j: pass pose i, pose j "
                "and the edge's measurement, in that order")
        k = table[key]
        return e_all[k].copy(), A_all[k].copy(), B_all[k].copy()

    original = getattr(edge_module, "edge_error_and_jacobians", None)
    patched = []
    if _exclusive() and original is not None:
        for module in (edge_module, assembly):
            for name, value in list(vars(module).items()):
                if value is original:
                    patched.append((module, name))
                    setattr(module, name, edge_error_and_jacobians)
    try:
        out = assembly.assemble_normal_equations(poses, edges_i, edges_j, measurements, information, fixed)
    finally:
        for module, name in patched:
            setattr(module, name, original)
    if not isinstance(out, tuple) or len(out) != 3:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (H, b, chi2)")
    H, b, chi2 = out
    import scipy.sparse as sp

    if sp.issparse(H):
        raise OutputError("returned H as a scipy sparse matrix: the per-edge loop returns a dense "
                          "(3N, 3N) numpy array (the framework takes its upper triangle)")
    return {"H": H, "b": b, "chi2": chi2}


# -- chapter 2: sparse solves


def upper_triangle(H, as_sparse, impl):
    """``sparse_solve.upper_triangle_csc`` of ``H`` given dense or as a scipy CSR matrix."""
    import scipy.sparse as sp

    H = np.asarray(H, dtype=float)
    given = sp.csr_matrix(H) if as_sparse else H
    out = impl.module("sparse_solve").upper_triangle_csc(given)
    is_sparse = sp.issparse(out)
    values = out.toarray() if is_sparse else np.asarray(out)
    return {
        "M": values,
        "sparse": float(is_sparse),
        "csc": float(is_sparse and getattr(out, "format", "") == "csc"),
        "format": encode_text(getattr(out, "format", type(out).__name__)),
    }


_COUNTING: dict = {}  # qdldl.Solver -> its counting subclass (one per process, so captures keep counting)


def _counting_solver(original):
    """A subclass of ``qdldl.Solver`` counting the objects made (``made``)."""
    if original not in _COUNTING:
        class Solver(original):
            made = 0

            def __init__(self, *args, **kwargs):
                Solver.made += 1
                super().__init__(*args, **kwargs)

        Solver.__module__, Solver.__qualname__ = original.__module__, original.__qualname__
        _COUNTING[original] = Solver
    return _COUNTING[original]


@contextmanager
def _sparse_solve_counted(impl):
    """``(module, counter)``: the implementation's ``sparse_solve`` with ``qdldl.Solver``
    counted (``counter.made``), or ``counter`` None where it cannot be (another thread runs).

    The counting class is installed in ``qdldl`` before the student's module is imported,
    so that ``from qdldl import Solver`` at import time takes it too, and over every name
    of the module bound to the original; both are restored afterwards.
    """
    import qdldl

    if not _exclusive():
        yield impl.module("sparse_solve"), None
        return
    original = qdldl.Solver
    counter = _counting_solver(original)
    counter.made = 0
    qdldl.Solver = counter
    module = None
    try:
        module = impl.module("sparse_solve")
        for name, value in list(vars(module).items()):
            if value is original:
                setattr(module, name, counter)
        yield module, counter
    finally:
        qdldl.Solver = original
        if module is not None:
            for name, value in list(vars(module).items()):
                if value is counter:
                    setattr(module, name, original)


def _solve_once(solver, shape, indices, indptr, data, b, what):
    import scipy.sparse as sp

    H = sp.csc_matrix((np.array(data, dtype=float), np.array(indices), np.array(indptr)), shape=tuple(shape))
    dx = solver.solve(H, np.array(b, dtype=float))
    if sp.issparse(dx):
        raise OutputError(f"returned a scipy sparse matrix on {what}, expected a (n,) array")
    return dx


def sparse_solves(shape, indices, indptr, values, rhs, impl):
    """One ``SparseCholeskySolver`` solving ``H_k dx = -b_k`` for k = 0, 1, ...

    Every ``H_k`` is the upper triangle in CSC with the same pattern (``indices``,
    ``indptr``) and its own ``values[k]``. Returns ``dx0, dx1, ...`` and
    ``solvers_created``, the number of ``qdldl.Solver`` objects made (NaN when they
    could not be counted).
    """
    out = {}
    with _sparse_solve_counted(impl) as (module, counter):
        solver = module.SparseCholeskySolver()
        for k, (data, b) in enumerate(zip(values, rhs)):
            out[f"dx{k}"] = _solve_once(solver, shape, indices, indptr, data, b, f"call {k + 1}")
        out["solvers_created"] = float(counter.made) if counter is not None else float("nan")
    return out


def alternating_solves(first, second, impl):
    """Two ``SparseCholeskySolver`` objects, one per pattern, called alternately.

    ``first`` and ``second`` are ``(shape, indices, indptr, values, rhs)`` as for
    :func:`sparse_solves`; the calls go first solver, second solver, first, second, ...
    Returns ``a0, a1, ...`` (the first solver's steps), ``b0, b1, ...`` (the second's)
    and ``solvers_created``.
    """
    out = {}
    with _sparse_solve_counted(impl) as (module, counter):
        solvers = (module.SparseCholeskySolver(), module.SparseCholeskySolver())
        for k in range(len(first[3])):
            for prefix, solver, (shape, indices, indptr, values, rhs), which in (
                    ("a", solvers[0], first, "first"), ("b", solvers[1], second, "second")):
                out[f"{prefix}{k}"] = _solve_once(solver, shape, indices, indptr, values[k], rhs[k],
                                                  f"the {which} solver's call {k + 1}")
        out["solvers_created"] = float(counter.made) if counter is not None else float("nan")
    return out


# -- chapter 2: the Ceres cost


def _ceres_cost(impl, measurement, sqrt_information):
    cls = impl.module("ceres_edge_cost").SE2EdgeCost
    try:
        return cls(np.array(measurement, dtype=float), np.array(sqrt_information, dtype=float))
    except NotImplementedError as exc:
        import pyceres

        class _Bare(cls):
            def __init__(self):
                pyceres.CostFunction.__init__(self)
                self.set_num_residuals(3)
                self.set_parameter_block_sizes([3, 3])

        todo = _stub_todo(lambda: _Bare().Evaluate([np.zeros(3), np.zeros(3)], np.zeros(3), None))
        raise NotImplementedError(f"{exc}; {todo}" if todo else str(exc)) from None


def ceres_cost(measurement, sqrt_information, x_i, x_j, impl):
    """Residuals (3,) and Jacobians (3, 3) of ``SE2EdgeCost`` as Ceres computes them
    (``CostFunction.evaluate``, which calls the student's ``Evaluate``)."""
    cost = _ceres_cost(impl, measurement, sqrt_information)
    residuals, jacobians = cost.evaluate(np.array(x_i, dtype=float), np.array(x_j, dtype=float))
    if residuals is None or jacobians is None:
        raise OutputError("made Ceres' evaluation fail: Evaluate must return True after filling "
                          "residuals and jacobians (it returned False or None)")
    return {"r": np.asarray(residuals).ravel(), "J_i": np.asarray(jacobians[0]),
            "J_j": np.asarray(jacobians[1])}


def ceres_partial_jacobians(measurement, sqrt_information, x_i, x_j, impl):
    """``Evaluate`` called directly with NaN-filled buffers: with both Jacobians requested
    (``both``), for residuals only (``none``: ``jacobians=None``) and for a constant block
    (``first``: ``[None, J_j]``, ``second``: ``[J_i, None]``), as Ceres does.

    Fields per request: ``{req}_r`` (3,), ``{req}_J`` (9,) (the requested Jacobian: J_i
    for ``both``, NaN for ``none``), ``{req}_J2`` (J_j for ``both``) and ``{req}_ok``
    (Evaluate returned True).
    """
    cost = _ceres_cost(impl, measurement, sqrt_information)
    parameters = [np.array(x_i, dtype=float), np.array(x_j, dtype=float)]
    out = {}
    for request in ("both", "none", "first", "second"):
        residuals = np.full(3, np.nan)
        buffers = {"both": [np.full(9, np.nan), np.full(9, np.nan)], "none": None,
                   "first": [None, np.full(9, np.nan)], "second": [np.full(9, np.nan), None]}[request]
        try:
            ok = cost.Evaluate([p.copy() for p in parameters], residuals, buffers)
        except Exception as exc:  # noqa: BLE001 - say which request failed, keep type and line
            what = {"both": "both jacobians requested",
                    "none": "jacobians=None (Ceres wants residuals only)",
                    "first": "jacobians=[None, J_j] (x_i is a constant block, e.g. a fixed pose)",
                    "second": "jacobians=[J_i, None] (x_j is a constant block)"}[request]
            exc.args = (f"{exc} (called with {what})",)
            raise
        out[f"{request}_ok"] = float(isinstance(ok, (bool, int, np.bool_)) and bool(ok))
        out[f"{request}_r"] = residuals
        out[f"{request}_J"] = np.full(9, np.nan) if buffers is None else next(
            buf for buf in buffers if buf is not None)
        out[f"{request}_J2"] = buffers[1] if request == "both" else np.full(9, np.nan)
    return out


# -- chapter 2, going further: the vectorized linearization


def _fallback_note(impl, graph, exc):
    """The stub's message, with a note when the per-edge loop would be used instead."""
    note = ""
    try:
        impl.module("pose_graph_assembly").assemble_normal_equations(
            graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"],
            graph["information"], graph["fixed"])
        note = " [the per-edge loop works]"
    except Exception:  # noqa: BLE001 - the loop is graded by its own checks
        pass
    return f"{exc}{note}"


def fast_edges(graph, impl):
    """``pose_graph_fast.edge_errors_and_jacobians`` on all edges of ``graph``."""
    fast = impl.module("pose_graph_fast")
    try:
        out = fast.edge_errors_and_jacobians(graph["poses"], graph["edges_i"], graph["edges_j"],
                                             graph["measurements"])
    except NotImplementedError as exc:
        raise NotImplementedError(_fallback_note(impl, graph, exc)) from None
    if not isinstance(out, tuple) or len(out) != 3:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (e, A, B)")
    return {"e": out[0], "A": out[1], "B": out[2]}


def fast_assemble(graph, blocks, impl):
    """``pose_graph_fast.SparseAssembler``: built once, ``assemble`` called for each of
    ``blocks`` (``(e, A, B)`` of every edge, from the reference), on the same pattern.

    Fields per call k: ``H{k}`` (dense copy of the returned matrix), ``b{k}``, ``chi2{k}``,
    ``csc{k}``; and ``diagonal_ok`` (1 when ``diagonal_positions`` points at the diagonal
    of ``H.data``, 0 when it does not, NaN when there is none).
    """
    import scipy.sparse as sp

    fast = impl.module("pose_graph_fast")
    cls = fast.SparseAssembler
    try:
        assembler = cls(len(graph["poses"]), graph["edges_i"], graph["edges_j"], graph["fixed"])
    except NotImplementedError as exc:
        e, A, B = blocks[0]
        todo = _stub_todo(lambda: cls.assemble(object.__new__(cls), e, A, B, graph["information"]))
        raise NotImplementedError(_fallback_note(impl, graph, f"{exc}; {todo}" if todo else exc)) from None
    out = {}
    H = None
    for k, (e, A, B) in enumerate(blocks):
        result = assembler.assemble(np.array(e), np.array(A), np.array(B), np.array(graph["information"]))
        if not isinstance(result, tuple) or len(result) != 3:
            raise OutputError(f"returned {type(result).__name__}, expected a tuple (H, b, chi2)")
        H, b, chi2 = result
        out[f"H{k}"] = H.toarray() if sp.issparse(H) else np.asarray(H)
        out[f"csc{k}"] = float(sp.issparse(H) and H.format == "csc")
        out[f"b{k}"], out[f"chi2{k}"] = b, chi2
    positions = getattr(assembler, "diagonal_positions", None)
    if positions is None or not (sp.issparse(H) and H.format == "csc"):
        out["diagonal_ok"] = float("nan")
    else:
        try:
            out["diagonal_ok"] = float(np.array_equal(H.data[np.asarray(positions)], H.diagonal()))
        except (IndexError, TypeError, ValueError):
            out["diagonal_ok"] = 0.0
    return out


# -- end-to-end runs of chapters 2 and 3


def minimize_pose_graph(graph, method, impl, problem_impl=None, vectorized=False):
    """``course.solver.minimize`` on a pose graph given as arrays.

    The problem (edge, assembly, sparse solve; ``vectorized=False``: the per-edge loop)
    comes from ``problem_impl`` (default ``impl``), the method's pieces from ``impl``.
    """
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver import minimize

    problem = PoseGraphProblem(_graph(graph), impl=impl if problem_impl is None else problem_impl,
                               vectorized=vectorized)
    return _summary(minimize(problem, method, impl=impl))


def minimize_curve_run(method, impl, num_points=100, seed=0):
    """Like :func:`minimize_curve`, with the trace summary (rejections, factorizations)."""
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import minimize

    problem = CurveProblem(generate(num_points=num_points, seed=seed), impl=impl)
    return _summary(minimize(problem, method, impl=impl))


# -- chapter 3: the dogleg step


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


# -- chapter 4: the parallel assembly graded alone

#: the stand-in kernel waits STAGGER_FLOOR + STAGGER_SECONDS * (1 - first / K) on a chunk whose first
#: observation is ``first`` (when it staggers): earlier chunks finish later
STAGGER_FLOOR, STAGGER_SECONDS = 0.002, 0.03
#: the per-observation blocks a stand-in kernel sums (the reference's, computed in the parent)
BLOCK_NAMES = ("U", "V", "W", "g_cam", "g_point", "chi2")


def stagger_delay(first, num_observations) -> float:
    """Seconds the stand-in kernel waits on a chunk starting at observation ``first``."""
    return STAGGER_FLOOR + STAGGER_SECONDS * (1.0 - first / max(num_observations, 1))


class BlockKernel:
    """The per-chunk assembly given to ``parallel_assembly.normal_equations_parallel`` when graded.

    It returns the sums of per-observation blocks that the reference computed in the parent
    (``blocks``: ``U`` (K, 9, 9), ``V`` (K, 3, 3), ``W`` (K, 9, 3), ``g_cam`` (K, 9),
    ``g_point`` (K, 3), ``chi2`` (K,)), so that the grade does not depend on the student's
    ``bundle_adjustment.normal_equations``. It finds a chunk's observations by their rows of
    ``r`` (unique in the grader's inputs), raises a ValueError that says what is wrong when the
    arrays of one call are not the same observations or a chunk is empty, and records the
    observations it was given (``seen``), the threads it ran on and the most calls running at
    once. With ``stagger`` it waits longer on earlier chunks (:func:`stagger_delay`), so that
    the chunks finish in another order than they were submitted and overlap in time.
    """

    def __init__(self, r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                 stagger=False):
        self.r = np.asarray(r, dtype=float)
        self.J_cam, self.J_point = np.asarray(J_cam, dtype=float), np.asarray(J_point, dtype=float)
        self.camera_index, self.point_index = np.asarray(camera_index), np.asarray(point_index)
        self.num_cameras, self.num_points = int(num_cameras), int(num_points)
        self.blocks = {name: np.asarray(blocks[name], dtype=float) for name in BLOCK_NAMES}
        self.stagger = bool(stagger)
        self.rows = {row.tobytes(): k for k, row in enumerate(self.r)}
        if len(self.rows) != len(self.r):
            raise ValueError("BlockKernel: the rows of r must be unique (the grader's inputs are)")
        self.lock = threading.Lock()
        self.seen = np.zeros(len(self.r), dtype=np.int64)
        self.calls = 0
        self.threads = set()
        self.running = 0
        self.most_at_once = 0

    def _rows_of(self, r):
        r = np.asarray(r, dtype=float)
        if r.ndim != 2 or r.shape[1] != 2:
            raise ValueError(f"kernel was called with r of shape {r.shape}, expected a chunk r[lo:hi] of shape (n, 2)")
        if len(r) == 0:
            raise ValueError("kernel was called with an empty chunk (0 observations): make every chunk non-empty "
                             "(with more chunks than observations, one observation per chunk)")
        rows = [self.rows.get(row.tobytes()) for row in r]
        if any(k is None for k in rows):
            raise ValueError("kernel was called with rows that are not rows of r: pass r[lo:hi] as it is")
        return np.array(rows, dtype=np.int64)

    def __call__(self, r, J_cam, J_point, camera_index, point_index, num_cameras, num_points):
        import time

        rows = self._rows_of(r)
        for name, given, full in (("J_cam", J_cam, self.J_cam), ("J_point", J_point, self.J_point),
                                  ("camera_index", camera_index, self.camera_index),
                                  ("point_index", point_index, self.point_index)):
            if not np.array_equal(np.asarray(given), full[rows]):
                raise ValueError(f"kernel was called with {name} of other observations than its r: slice r, "
                                 "J_cam, J_point, camera_index and point_index with the same chunk [lo:hi]")
        if (num_cameras, num_points) != (self.num_cameras, self.num_points):
            raise ValueError(f"kernel was called with num_cameras, num_points = {num_cameras!r}, {num_points!r}, "
                             f"expected {self.num_cameras}, {self.num_points} (every chunk has all cameras and points)")
        with self.lock:
            self.calls += 1
            self.running += 1
            self.most_at_once = max(self.most_at_once, self.running)
            self.threads.add(threading.get_ident())
            np.add.at(self.seen, rows, 1)
        try:
            if self.stagger:
                time.sleep(stagger_delay(int(rows.min()), len(self.r)))
            b = self.blocks
            U, V = np.zeros((self.num_cameras, 9, 9)), np.zeros((self.num_points, 3, 3))
            g_cam, g_point = np.zeros((self.num_cameras, 9)), np.zeros((self.num_points, 3))
            for total, name, index in ((U, "U", self.camera_index), (V, "V", self.point_index),
                                       (g_cam, "g_cam", self.camera_index), (g_point, "g_point", self.point_index)):
                np.add.at(total, index[rows], b[name][rows])
            return U, V, b["W"][rows].copy(), g_cam, g_point, float(np.sum(b["chi2"][rows]))
        finally:
            with self.lock:
                self.running -= 1


def parallel_normal_equations(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                              impl, workers=2, chunks=None, stagger=True):
    """``parallel_assembly.normal_equations_parallel`` with a :class:`BlockKernel` as ``kernel``.

    Returns its six outputs (``U``, ``V``, ``W``, ``g_cam``, ``g_point``, ``chi2``) and what the
    kernel saw: ``calls``, ``threads`` (distinct threads), ``most_at_once`` (kernel calls
    running at the same time), ``missing`` (observations never passed), ``repeated`` (passes
    beyond the first), ``first_missing`` and ``first_repeated`` (-1: none).
    """
    kernel = BlockKernel(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, blocks,
                         stagger=stagger)
    function = impl.module("parallel_assembly").normal_equations_parallel
    out = function(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points, workers=workers,
                   chunks=chunks, kernel=kernel)
    if not isinstance(out, tuple) or len(out) != 6:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (U, V, W, g_cam, g_point, chi2)")
    if kernel.calls == 0 and len(kernel.r):
        raise OutputError("never called its kernel argument: assemble every chunk with kernel(r[lo:hi], "
                          "J_cam[lo:hi], ...), which is bundle_adjustment.normal_equations unless given")
    seen = kernel.seen
    missing, repeated = np.flatnonzero(seen == 0), np.flatnonzero(seen > 1)
    return {**dict(zip(BLOCK_NAMES, out)), "calls": float(kernel.calls), "threads": float(len(kernel.threads)),
            "most_at_once": float(kernel.most_at_once), "missing": float(len(missing)),
            "repeated": float(np.sum(seen[repeated] - 1)),
            "first_missing": float(missing[0]) if len(missing) else -1.0,
            "first_repeated": float(repeated[0]) if len(repeated) else -1.0}
