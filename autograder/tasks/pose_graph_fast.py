"""The vectorized linearization: all edges at once, and the sparse assembler
(``checks/pose_graph_fast.py``)."""

import numpy as np

from autograder.tasks.common import OutputError, stub_todo


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
        todo = stub_todo(lambda: cls.assemble(object.__new__(cls), e, A, B, graph["information"]))
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
