"""The reference sparse assemblers of chapters 6 and 7 equal the dense sums they stand for.

``pose_graph_3d_assembly.SparseAssembler3D`` and ``factor_linearisation.BlockSparseAssembler`` compute each
slot pair's block once and sum the entries into ``H.data`` through a sparse 0/1 matrix built once; here
against ``H = sum J^T Omega J`` formed densely, on random graphs that reach every case of that summation:
edges and slot pairs in both orders (mirrored entries), one variable in two slots of a factor (its diagonal
entries counted twice), priors, mixed tangent sizes, fixed variables, the per-variable grouping of a
variable's own block, and a second call on the same pattern.
"""

import numpy as np
import pytest

from course.core import impl as impl_loader
from course.geometry.so3 import exp_many


def _held(H, b, fixed_dof):
    """Dense H and b with the fixed dofs held: zero rows, columns and b, unit diagonal."""
    H[fixed_dof, :], H[:, fixed_dof], b[fixed_dof] = 0.0, 0.0, 0.0
    H[fixed_dof, fixed_dof] = 1.0
    return np.triu(H), b


@pytest.mark.parametrize("seed", range(40))
def test_block_sparse_assembler_is_the_dense_sum(seed):
    assembler = impl_loader.load("solutions").module("factor_linearisation").BlockSparseAssembler
    rng = np.random.default_rng(seed)
    dims = rng.choice([2, 3, 6], int(rng.integers(1, 10)))
    offsets = np.concatenate([[0], np.cumsum(dims)])
    keys, calls = [], [[], []]
    for _ in range(int(rng.integers(1, 4))):
        slot_dims = [int(rng.choice(np.unique(dims))) for _ in range(int(rng.integers(1, 4)))]
        count, m = int(rng.integers(1, 30)), int(rng.integers(1, 7))
        keys.append(np.stack([rng.choice(np.flatnonzero(dims == d), count) for d in slot_dims], axis=1))
        for call in calls:
            call.append((rng.normal(size=(count, m)), [rng.normal(size=(count, m, d)) for d in slot_dims]))
    fixed = rng.choice(len(dims), int(rng.integers(0, min(len(dims), 2) + 1)), replace=False)
    built = assembler(dims, keys, fixed)
    fixed_dof = np.concatenate([np.arange(offsets[v], offsets[v + 1]) for v in fixed] + [np.zeros(0, int)])
    for blocks in calls:
        H, b, chi2 = built.assemble(blocks)
        dense, g, want = np.zeros((offsets[-1],) * 2), np.zeros(offsets[-1]), 0.0
        for key, (r, J) in zip(keys, blocks):
            for f in range(len(key)):
                row = np.zeros((r.shape[1], offsets[-1]))
                for a, v in enumerate(key[f]):
                    row[:, offsets[v]:offsets[v + 1]] += J[a][f]
                dense += row.T @ row
                g += row.T @ r[f]
                want += float(r[f] @ r[f])
        dense, g = _held(dense, g, fixed_dof)
        scale = max(1.0, float(np.abs(dense).max()))
        np.testing.assert_allclose(H.toarray(), dense, rtol=0, atol=1e-13 * scale)
        np.testing.assert_allclose(b, g, rtol=0, atol=1e-13 * max(1.0, float(np.abs(g).max())))
        assert chi2 == pytest.approx(want, rel=1e-13)
        assert np.array_equal(H.data[built.diagonal_positions], np.diag(H.toarray()))


def test_block_sparse_assembler_groups_a_busy_variables_own_block():
    """Where a slot's variables are in many factors each, their own block is summed variable by variable."""
    assembler = impl_loader.load("solutions").module("factor_linearisation").BlockSparseAssembler
    rng = np.random.default_rng(7)
    keys = rng.integers(0, 4, (120, 2))
    blocks = [(rng.normal(size=(120, 6)), [rng.normal(size=(120, 6, 6)) for _ in range(2)])]
    built = assembler(np.full(4, 6), [keys], [2])  # 30 factors per variable: the reference groups them
    H, b, _ = built.assemble(blocks)
    dense, g = np.zeros((24, 24)), np.zeros(24)
    for f, (i, j) in enumerate(keys):
        row = np.zeros((6, 24))
        row[:, 6 * i:6 * i + 6] += blocks[0][1][0][f]
        row[:, 6 * j:6 * j + 6] += blocks[0][1][1][f]
        dense += row.T @ row
        g += row.T @ blocks[0][0][f]
    dense, g = _held(dense, g, np.arange(12, 18))
    np.testing.assert_allclose(H.toarray(), dense, rtol=0, atol=1e-12 * np.abs(dense).max())
    np.testing.assert_allclose(b, g, rtol=0, atol=1e-12 * np.abs(g).max())


@pytest.mark.parametrize("seed", range(10))
def test_sparse_assembler_3d_is_the_dense_sum(seed):
    assembler = impl_loader.load("solutions").module("pose_graph_3d_assembly").SparseAssembler3D
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(2, 9)), int(rng.integers(1, 25))
    edges_i = rng.integers(0, n, m)
    edges_j = (edges_i + rng.integers(1, n, m)) % n  # both orders, no self-loop
    fixed = rng.choice(n, int(rng.integers(0, 3)), replace=False)
    L = rng.normal(size=(m, 6, 6)) + 3.0 * np.eye(6)
    information = L @ L.transpose(0, 2, 1)
    built = assembler(n, edges_i, edges_j, fixed)
    fixed_dof = (6 * fixed[:, None] + np.arange(6)).ravel()
    for _ in range(2):
        e, A, B = rng.normal(size=(m, 6)), rng.normal(size=(m, 6, 6)), rng.normal(size=(m, 6, 6))
        A[:, :3, :3] = -exp_many(rng.normal(size=(m, 3)))  # blocks of the sizes the edges give
        H, b, chi2 = built.assemble(e, A, B, information)
        dense, g = np.zeros((6 * n, 6 * n)), np.zeros(6 * n)
        for k, (i, j) in enumerate(zip(edges_i, edges_j)):
            row = np.zeros((6, 6 * n))
            row[:, 6 * i:6 * i + 6], row[:, 6 * j:6 * j + 6] = A[k], B[k]
            dense += row.T @ information[k] @ row
            g += row.T @ information[k] @ e[k]
        want = float(np.einsum("mi,mij,mj->", e, information, e))
        dense, g = _held(dense, g, fixed_dof)
        np.testing.assert_allclose(H.toarray(), dense, rtol=0, atol=1e-13 * np.abs(dense).max())
        np.testing.assert_allclose(b, g, rtol=0, atol=1e-13 * max(1.0, float(np.abs(g).max())))
        assert chi2 == pytest.approx(want, rel=1e-13)
        assert np.array_equal(H.data[built.diagonal_positions], np.diag(H.toarray()))
