"""GTSAM's ``Marginals`` of a linear system given by its information H, block by block.

The same linearisation as ours, in our tangent: one ``HessianFactor`` per variable (its diagonal block
of H) and one per pair of variables that H couples (the off-diagonal block, zero diagonal blocks), summed
by GTSAM's elimination into H itself. GTSAM then orders the variables (COLAMD), eliminates them into its
Bayes tree (multifrontal Cholesky) and ``marginalCovariance`` reads each block off it.
"""

import time

import numpy as np
import scipy.sparse as sp


def linear_graph(H_upper, starts):
    """``(GaussianFactorGraph, VectorValues)`` of H (its upper triangle, (n, n)) whose variables are the
    blocks ``starts`` (m + 1,), keyed ``0..m-1``; the values 0."""
    import gtsam

    m = len(starts) - 1
    owner = np.repeat(np.arange(m), np.diff(starts))
    coo = sp.coo_matrix(H_upper)
    pairs = {(int(u), int(v)) for u, v in zip(owner[coo.row], owner[coo.col])}
    dense = sp.csr_matrix(H_upper)
    graph = gtsam.GaussianFactorGraph()
    values = gtsam.VectorValues()
    for v in range(m):
        a, b = starts[v], starts[v + 1]
        block = dense[a:b, a:b].toarray()
        block = np.triu(block) + np.triu(block, 1).T
        graph.push_back(gtsam.HessianFactor(v, block, np.zeros(b - a), 0.0))
        values.insert(v, np.zeros(b - a))
    for u, v in sorted(pairs):
        if u == v:
            continue
        u, v = min(u, v), max(u, v)
        du, dv = starts[u + 1] - starts[u], starts[v + 1] - starts[v]
        coupling = dense[starts[u]:starts[u + 1], starts[v]:starts[v + 1]].toarray()
        graph.push_back(gtsam.HessianFactor(u, v, np.zeros((du, du)), coupling, np.zeros(du), np.zeros((dv, dv)),
                                            np.zeros(dv), 0.0))
    return graph, values


def marginals(H_upper, starts, keys) -> tuple[list, float]:
    """``([Sigma_k (d, d) for k in keys], seconds)``: GTSAM's ``Marginals`` of H made and
    ``marginalCovariance`` of every key (variable indices), timed; the graph's making not."""
    import gtsam

    graph, values = linear_graph(H_upper, starts)
    start = time.perf_counter()
    marginal = gtsam.Marginals(graph, values)
    out = [np.asarray(marginal.marginalCovariance(int(k))) for k in keys]
    return out, time.perf_counter() - start
