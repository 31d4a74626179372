"""The 3D sparse assembler, built once and called twice (``checks/pose_graph_3d_assembly.py``)."""

import numpy as np

from autograder.tasks.common import OutputError, stub_todo


def assemble_twice(graph, blocks, impl):
    """``pose_graph_3d_assembly.SparseAssembler3D`` built on ``graph``'s edges, ``assemble``
    called for each of ``blocks`` (``(e, A, B)`` from the reference) on the same pattern.

    Fields per call k: ``H{k}`` (dense copy), ``b{k}``, ``chi2{k}``, ``csc{k}``; and
    ``diagonal_ok`` (1 when ``diagonal_positions`` points at H's diagonal in ``H.data``, 0
    when it does not, NaN when there is none).
    """
    import scipy.sparse as sp

    cls = impl.module("pose_graph_3d_assembly").SparseAssembler3D
    try:
        assembler = cls(graph["num_poses"], graph["edges_i"], graph["edges_j"], graph["fixed"])
    except NotImplementedError as exc:
        e, A, B = blocks[0]
        todo = stub_todo(lambda: cls.assemble(object.__new__(cls), e, A, B, graph["information"]))
        raise NotImplementedError(f"{exc}; {todo}" if todo else str(exc)) from None
    out, H = {}, None
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
