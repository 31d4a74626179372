# RELEASE: omit
"""Known mistakes in ``parallel_assembly`` (see ``autograder.mistakes``): the chunk bounds with
one slip, and the parallel assembly's outputs when a chunk is dropped, chunks overlap, a
partial sum is overwritten instead of added, or W is collected in completion order.

The assembly's outputs are sums of the per-observation blocks the call carries, each
observation counted ``m_k`` times (:func:`_sums`); the chunks are those of the reference's
``chunk_bounds``, and the completion order is the stand-in kernel's schedule
(``autograder.tasks.parallel_assembly.stagger_delay``) on ``workers`` threads.
"""

import numpy as np

from autograder.checks.parallel_assembly import BOUNDS, PARALLEL
from autograder.tasks.parallel_assembly import stagger_delay


def _bounds(K, chunks, *, remainder=True, clamp=True, ceil=False):
    """The reference's chunk bounds, or one slip: the remainder dropped, ``n = chunks`` even
    when chunks > K (empty chunks), or chunks of ``ceil(K / n)`` (the last one short)."""
    n = min(chunks, K) if clamp else chunks
    if n == 0:
        return np.zeros(1)
    if ceil:
        size = -(-K // n)
        return np.array(sorted({min(k * size, K) for k in range(n + 1)}), dtype=float)
    size, extra = divmod(K, n)
    return np.array([k * size + (min(k, extra) if remainder else 0) for k in range(n + 1)], dtype=float)


def bounds_mistakes(call, ref):
    K, chunks = call.args
    known = []
    for slip, why in (({"remainder": False}, "the remainder K mod n was dropped: the last observations are in no "
                                            "chunk (give K mod n chunks one observation more)"),
                      ({"clamp": False}, "with more chunks than observations some chunks are empty: use "
                                         "n = min(chunks, num_observations)"),
                      ({"ceil": True}, "chunks of ceil(K / n) observations leave the last one short (or fewer "
                                       "chunks than asked): sizes K // n and K // n + 1 balance the threads")):
        value = _bounds(K, chunks, **slip)
        if value.shape != np.shape(ref["value"]) or not np.array_equal(value, ref["value"]):
            known.append((value, why))
    return {"value": known}


def _sums(call, counts) -> dict:
    """The six outputs with observation k counted ``counts[k]`` times (W: observation order)."""
    r, _, _, ci, pi, C, P, blocks = call.args
    counts = np.asarray(counts, dtype=float)
    out = {"U": np.zeros((C, 9, 9)), "V": np.zeros((P, 3, 3)), "g_cam": np.zeros((C, 9)), "g_point": np.zeros((P, 3))}
    for name, index in (("U", ci), ("V", pi), ("g_cam", ci), ("g_point", pi)):
        weights = counts.reshape((-1,) + (1,) * (np.ndim(blocks[name]) - 1))
        np.add.at(out[name], index, weights * blocks[name])
    out["chi2"] = np.asarray(float(np.sum(counts * blocks["chi2"])))
    out["W"] = np.asarray(blocks["W"], dtype=float)
    return out


def _chunks(call):
    K = len(call.args[0])
    workers, chunks = call.kwargs["workers"], call.kwargs["chunks"]
    b = _bounds(K, workers if chunks is None else chunks).astype(int)
    return list(zip(b[:-1], b[1:])), workers


def _completion_order(pieces, workers, K) -> list:
    """Chunk numbers in the order the stand-in kernel finishes them on ``workers`` threads."""
    free = [0.0] * workers
    done = []
    for number, (lo, _) in enumerate(pieces):
        slot = int(np.argmin(free))
        free[slot] += stagger_delay(lo, K)
        done.append((free[slot], number))
    return [number for _, number in sorted(done)]


def parallel_mistakes(call, ref, names=("U", "V", "W", "g_cam", "g_point", "chi2")):
    K = len(call.args[0])
    pieces, workers = _chunks(call)
    blocks = call.args[7]
    outputs = []
    if K % max(len(pieces), 1):
        n = len(pieces)
        kept = np.zeros(K)
        kept[:(K // n) * n] = 1.0
        outputs.append((_sums(call, kept), ("U", "V", "g_cam", "g_point", "chi2"),
                        "the last K mod n observations were dropped (the remainder of K / n chunks)"))
    twice = np.ones(K)
    for lo, _ in pieces[1:]:
        twice[lo] += 1.0
    outputs.append((_sums(call, twice), ("U", "V", "g_cam", "g_point", "chi2"),
                    "the chunks overlap: the first observation of each chunk is also in the previous one "
                    "(slice [lo:hi], hi excluded)"))
    last = np.zeros(K)
    if pieces:
        last[pieces[-1][0]:pieces[-1][1]] = 1.0
    only_last = _sums(call, last)
    for name in ("U", "V", "g_cam", "g_point"):
        outputs.append(({name: only_last[name]}, (name,), f"{name} holds the last chunk's partial sum only: add "
                                                          f"every chunk's (+=), do not overwrite it"))
    outputs.append(({"chi2": only_last["chi2"]}, ("chi2",), "chi2 of the last chunk only: add every chunk's chi2"))
    order = _completion_order(pieces, workers, K)
    W = np.asarray(blocks["W"], dtype=float)
    outputs.append(({"W": np.concatenate([W[pieces[i][0]:pieces[i][1]] for i in order]) if pieces else W}, ("W",),
                    "W is in the order the chunks completed (as_completed): keep the order of submission"))
    known = {name: [] for name in names}
    for values, affected, why in outputs:
        for name in set(affected) & set(names):
            value = np.asarray(values[name], dtype=float)
            want = np.asarray(ref[name], dtype=float)
            if value.shape != want.shape or not np.allclose(value, want, rtol=1e-12, atol=1e-12):
                known[name].append((value, why))
    return known


MISTAKES = {
    f"{BOUNDS}: contiguous balanced chunks": bounds_mistakes,
    f"{PARALLEL}: U, V and W as the serial assembly": lambda call, ref: parallel_mistakes(call, ref, ("U", "V", "W")),
    f"{PARALLEL}: gradients and chi2 as the serial assembly":
        lambda call, ref: parallel_mistakes(call, ref, ("g_cam", "g_point", "chi2")),
}
