"""The vectorized linearization: all edges at once, and the sparse assembler
(``checks/pose_graph_fast.py``)."""


from autograder.tasks.common import OutputError, assemble_each, stub_todo


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

    Fields: as ``autograder.tasks.common.assemble_each``.
    """
    fast = impl.module("pose_graph_fast")
    cls = fast.SparseAssembler
    try:
        assembler = cls(len(graph["poses"]), graph["edges_i"], graph["edges_j"], graph["fixed"])
    except NotImplementedError as exc:
        e, A, B = blocks[0]
        todo = stub_todo(lambda: cls.assemble(object.__new__(cls), e, A, B, graph["information"]))
        raise NotImplementedError(_fallback_note(impl, graph, f"{exc}; {todo}" if todo else exc)) from None
    return assemble_each(assembler, blocks, graph["information"])
