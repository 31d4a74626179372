"""The 3D sparse assembler, built once and called twice (``checks/pose_graph_3d_assembly.py``)."""

from autograder.tasks.common import assemble_each, stub_todo


def assemble_twice(graph, blocks, impl):
    """``pose_graph_3d_assembly.SparseAssembler3D`` built on ``graph``'s edges, ``assemble``
    called for each of ``blocks`` (``(e, A, B)`` from the reference) on the same pattern.
    Fields: as ``autograder.tasks.common.assemble_each``."""
    cls = impl.module("pose_graph_3d_assembly").SparseAssembler3D
    try:
        assembler = cls(graph["num_poses"], graph["edges_i"], graph["edges_j"], graph["fixed"])
    except NotImplementedError as exc:
        e, A, B = blocks[0]
        todo = stub_todo(lambda: cls.assemble(object.__new__(cls), e, A, B, graph["information"]))
        raise NotImplementedError(f"{exc}; {todo}" if todo else str(exc)) from None
    return assemble_each(assembler, blocks, graph["information"])
