"""The marginal covariances and the joint marginal, called on a scipy.sparse R built from its arrays
(``checks/marginal_covariances.py``): the inputs are stored as plain arrays, the student's function
gets the matrix the contract names."""

import numpy as np

from autograder.tasks.common import OutputError


def matrix(n, fmt, indptr, indices, data):
    """R (n, n) as a scipy.sparse ``fmt`` ("csr" or "csc") matrix from its arrays, stored zeros kept."""
    import scipy.sparse as sp

    kind = {"csr": sp.csr_matrix, "csc": sp.csc_matrix}[fmt]
    return kind((np.array(data, dtype=float), np.array(indices, dtype=np.int32), np.array(indptr, dtype=np.int32)),
                shape=(int(n), int(n)))


def marginals(n, fmt, indptr, indices, data, sizes, impl):
    """``marginal_covariances(R, sizes)``, its blocks checked for number and shape. Field ``blocks``: every
    block's entries, row by row, one variable after another (sum of d_v^2,)."""
    sizes = [int(d) for d in sizes]
    out = impl.module("marginal_covariances").marginal_covariances(matrix(n, fmt, indptr, indices, data), sizes)
    if isinstance(out, np.ndarray) or not hasattr(out, "__len__"):
        raise OutputError(f"returned {type(out).__name__}, expected a list of (d_v, d_v) arrays, one per variable")
    if len(out) != len(sizes):
        raise OutputError(f"returned {len(out)} blocks, expected one per variable ({len(sizes)})")
    flat = []
    for v, (block, d) in enumerate(zip(out, sizes)):
        try:
            block = np.asarray(block, dtype=float)
        except (TypeError, ValueError) as exc:
            raise OutputError(f"returned a block {v} that is not an array of numbers: {exc}") from None
        if block.shape != (d, d):
            raise OutputError(f"returned a block {v} of shape {block.shape}, expected ({d}, {d}) (variable {v}'s "
                              f"size is {d})")
        flat.append(block.ravel())
    return {"blocks": np.concatenate(flat)}


def joint(n, fmt, indptr, indices, data, sizes, keys, impl):
    """``joint_marginal(R, sizes, keys)``. Field ``Sigma`` (sum d, sum d)."""
    sizes, keys = [int(d) for d in sizes], [int(k) for k in keys]
    out = impl.module("marginal_covariances").joint_marginal(matrix(n, fmt, indptr, indices, data), sizes, keys)
    return {"Sigma": np.asarray(out, dtype=float)}
