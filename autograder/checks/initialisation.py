"""Checks of ``initialisation``: the spanning-tree start, the chordal rotations and the
translations given the rotations, each graded alone on small graphs.

Public inputs: an 8-pose loop (odometry, three loop closures, one written from a later to
an earlier pose, angles that cross +-pi) with noisy measurements, full information
matrices and varied rotation weights, anchored at pose 0 and at pose 4, and a second
graph whose edges are listed out of order or whose translation information blocks are
multiples of the identity; hidden inputs: other graphs of the same kinds from the hidden
seed. At the edges: a single pose with no edge (N = 1, M = 0), two poses joined by one edge
written from pose 1 to pose 0, and (rotations, translations) a 3-pose graph with two edges
from the anchor to the same pose and diagonal anisotropic information. Angles are compared
modulo 2 pi. The tree's graphs have one breadth-first tree only (every vertex one edge to
the depth before it), so any breadth-first search is right.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, wrap
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("initialisation",)
TREE = "initialisation.spanning_tree_poses"
ROTATIONS = "initialisation.chordal_rotations"
TRANSLATIONS = "initialisation.chordal_translations"

# ---------------------------------------------------------------- inputs


def _information(rng, count, isotropic=False):
    """(count, 3, 3) information matrices: full ones with rotation weights over two decades,
    or translation blocks ``a I`` (no cross terms) when ``isotropic``."""
    info = []
    for _ in range(count):
        if isotropic:
            a, w = rng.uniform(5.0, 50.0), rng.uniform(10.0, 400.0)
            info.append(np.diag((a, a, w)))
            continue
        L = rng.normal(size=(3, 3)) * (4.0, 4.0, 2.0)
        om = L @ L.T + np.diag((3.0, 3.0, 1.0))
        om[2, 2] *= rng.uniform(1.0, 100.0)  # a weight that matters: rotation weights over two decades
        om[:2, 2] = om[2, :2] = 0.3 * om[:2, 2]  # cross terms the translations must ignore, kept definite
        info.append(om)
    return np.array(info)


def _between(a, b):
    """(M, 3) the pose b seen from pose a (``x_a^-1 o x_b``), angles wrapped."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    d = b[:, :2] - a[:, :2]
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], wrap(b[:, 2] - a[:, 2])])


def _loop(rng, num_poses):
    """Poses on a noisy loop whose headings turn through +-pi."""
    phase = np.sort(rng.uniform(0, 2 * np.pi, num_poses)) if num_poses > 8 else np.linspace(0, 2 * np.pi, num_poses,
                                                                                             endpoint=False)
    phase = phase + rng.uniform(-0.15, 0.15, num_poses)
    radius = rng.uniform(3.0, 6.0)
    return np.column_stack([radius * np.cos(phase) + rng.normal(0, 0.3, num_poses),
                            radius * np.sin(phase) + rng.normal(0, 0.3, num_poses),
                            wrap(phase + np.pi / 2 + rng.normal(0, 0.2, num_poses))])


def _unique_tree(n, pairs, anchor):
    """Whether every vertex has one edge only to a vertex one hop nearer ``anchor``: then every
    breadth-first search gives the same tree, whatever order it visits the edges in."""
    depth, frontier = {anchor: 0}, [anchor]
    while frontier:
        nxt = []
        for u in frontier:
            for i, j in pairs:
                for a, b in ((i, j), (j, i)):
                    if a == u and b not in depth:
                        depth[b] = depth[u] + 1
                        nxt.append(b)
        frontier = nxt
    if len(depth) < n:
        return False
    return all(sum(1 for i, j in pairs if {depth.get(i), depth.get(j)} == {depth[v], depth[v] - 1}
                   and v in (i, j)) == 1 for v in range(n) if v != anchor)


@cache
def graph(seed=None, variant="loop"):
    """A small pose graph as a dict of arrays: ``num_poses``, ``edges_i``, ``edges_j``,
    ``measurements`` (noisy), ``information``, ``truth`` and a text for feedback.

    ``variant``: "loop" (8 poses, chain + three closures, one backwards), "isotropic" (the
    same with translation information ``a I``), and for the tree, whose breadth-first tree
    is then the same for every visiting order: "tree" (8 poses, chain + closures, unique
    from poses 0 and 4) and "shuffled" (7 poses, edges listed out of order, unique from 0)."""
    tag = {"loop": 1, "shuffled": 2, "isotropic": 3, "tree": 4}[variant]
    rng = np.random.default_rng([41, tag] if seed is None else [seed, 241, tag])
    n = 7 if variant == "shuffled" else 8
    truth = _loop(rng, n)
    chain = [(k, k + 1) for k in range(n - 1)]
    anchors = {"tree": (0, 4), "shuffled": (0,)}.get(variant, ())
    while True:
        closures = [(0, n - 1)] if variant in ("loop", "isotropic") else []
        while len(closures) < 3:
            i, j = (int(v) for v in rng.choice(n, 2, replace=False))
            if abs(i - j) > 1 and (i, j) not in closures and (j, i) not in closures:
                closures.append((max(i, j), min(i, j)) if len(closures) == 1 else (min(i, j), max(i, j)))
        pairs = chain + closures
        if all(_unique_tree(n, pairs, a) for a in anchors):
            break
    if variant == "shuffled":
        pairs = [pairs[k] for k in rng.permutation(len(pairs))]
    ei, ej = (np.array(v, dtype=np.int64) for v in zip(*pairs))
    z = _between(truth[ei], truth[ej]) + rng.normal(size=(len(pairs), 3)) * (0.15, 0.15, 0.08)
    z[:, 2] = wrap(z[:, 2])
    info = _information(rng, len(pairs), isotropic=variant == "isotropic")
    back = [(int(i), int(j)) for i, j in pairs if i > j]
    text = (f"{'an' if n == 8 else 'a'} {n}-pose graph with {len(pairs)} edges"
            + (", listed out of order" if variant == "shuffled" else "")
            + (f" (edge {back[0][0]} -> {back[0][1]} goes backwards)" if back else "")
            + (", translation information a I" if variant == "isotropic" else ""))
    return {"num_poses": n, "edges_i": ei, "edges_j": ej, "measurements": z, "information": info,
            "truth": truth, "text": text}


@cache
def small(seed=None, variant="pair"):
    """The smallest graphs: "single" (one pose, no edge), "pair" (two poses, one edge from pose 1 to pose 0,
    full information) and "parallel" (three poses, two edges from pose 0 to pose 1, diagonal anisotropic
    information), as :func:`graph`."""
    tag = {"single": 5, "pair": 6, "parallel": 7}[variant]
    rng = np.random.default_rng([41, tag] if seed is None else [seed, 241, tag])
    pairs = {"single": [], "pair": [(1, 0)], "parallel": [(0, 1), (1, 2), (0, 1), (2, 0)]}[variant]
    n = {"single": 1, "pair": 2, "parallel": 3}[variant]
    truth = _loop(rng, max(n, 2))[:n]
    ei, ej = (np.array([p[k] for p in pairs], dtype=np.int64) for k in (0, 1))
    z = _between(truth[ei], truth[ej]) + rng.normal(size=(len(pairs), 3)) * (0.15, 0.15, 0.08)
    z[:, 2] = wrap(z[:, 2])
    if variant == "parallel":  # translation weights unequal by construction
        d = np.sort(rng.uniform(2.0, 40.0, (len(pairs), 2)), axis=1) * (1.0, 3.0)
        info = np.array([np.diag((a, b, w)) for (a, b), w in zip(d, rng.uniform(10.0, 400.0, len(pairs)))])
    else:
        info = _information(rng, len(pairs)).reshape(len(pairs), 3, 3)
    text = {"single": "a single pose with no edge",
            "pair": "a 2-pose graph with one edge, from pose 1 to pose 0",
            "parallel": "a 3-pose graph with two edges from pose 0 to pose 1, diagonal anisotropic information",
            }[variant]
    return {"num_poses": n, "edges_i": ei, "edges_j": ej, "measurements": z.reshape(len(pairs), 3),
            "information": info, "truth": truth, "text": text}


def _anchor(g, k):
    """Anchor ``k`` at its true pose moved by a fixed offset (not the origin, heading near pi)."""
    pose = g["truth"][k] + (0.7, -1.1, 0.0)
    pose[2] = wrap(2.9 if k == 0 else pose[2])
    return pose


def _tree_calls(seed=None):
    calls = []
    for variant, anchor in (("tree", 0), ("tree", 4), ("shuffled", 0), ("single", 0), ("pair", 0)):
        g = graph(seed, variant) if variant in ("tree", "shuffled") else small(seed, variant)
        pose = _anchor(g, anchor)
        args = (g["num_poses"], g["edges_i"], g["edges_j"], g["measurements"], pose)
        calls.append(Call(f"initialisation:{TREE.split('.')[1]}", args, {"anchor": anchor},
                          where=f"on {g['text']}, anchor pose {anchor} at {tuple(np.round(pose, 3).tolist())}"))
    return calls


def _rotation_calls(seed=None):
    calls = []
    for variant, anchor in (("loop", 0), ("loop", 4), ("shuffled", 2), ("single", 0), ("pair", 0), ("parallel", 0)):
        g = graph(seed, variant) if variant in ("loop", "shuffled") else small(seed, variant)
        theta = float(_anchor(g, anchor)[2])
        args = (g["num_poses"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], theta)
        calls.append(Call(f"initialisation:{ROTATIONS.split('.')[1]}", args, {"anchor": anchor},
                          where=f"on {g['text']}, anchor pose {anchor} at theta {theta:.4g}"))
    return calls


def _translation_calls(seed=None):
    calls = []
    for variant, anchor in (("loop", 0), ("loop", 5), ("isotropic", 0), ("single", 0), ("pair", 0), ("parallel", 0)):
        g = graph(seed, variant) if variant in ("loop", "isotropic") else small(seed, variant)
        rng = np.random.default_rng([7, anchor] if seed is None else [seed, 243, anchor])
        theta = wrap(g["truth"][:, 2] + rng.normal(0, 0.05, g["num_poses"]))  # given, not computed here
        xy = _anchor(g, anchor)[:2]
        theta[anchor] = _anchor(g, anchor)[2]
        args = (g["num_poses"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], theta, xy)
        calls.append(Call(f"initialisation:{TRANSLATIONS.split('.')[1]}", args, {"anchor": anchor},
                          where=f"on {g['text']}, given orientations, anchor pose {anchor} at "
                                f"{tuple(np.round(xy, 3).tolist())}"))
    return calls


# ---------------------------------------------------------------- judges


def _aligned(value, want, angles):
    """``value`` with its angle entries moved by whole turns next to ``want``'s."""
    value = np.array(value, dtype=float)
    want = np.asarray(want, dtype=float)
    if value.shape != want.shape:
        return value
    if angles is Ellipsis:
        return want + wrap(value - want)
    value[..., angles] = want[..., angles] + wrap(value[..., angles] - want[..., angles])
    return value


def _judge(label, rtol, atol, angles=None, cause=""):
    """Compare every call's ``value`` with the reference, angles (``angles``: an index into
    the last axis, or Ellipsis for all) modulo 2 pi; known mistakes name the cause."""

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            actual, expected = np.asarray(got["value"], dtype=float), np.asarray(want["value"], dtype=float)
            known = list(ctx.known(index).get("value", ()))
            if angles is not None:
                actual = _aligned(actual, expected, angles)
                # a known mistake matches modulo 2 pi: aligned to the output itself, since an angle pi away
                # from the reference may round to +pi for one and -pi for the other
                known = [(_aligned(v, actual, angles), text) for v, text in known]
            text = compare(actual, expected, label, rtol, atol, call.where, known, cause)
            if text:
                return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


CHECKS = [
    check(TREE, "poses along the breadth-first tree", 4, _tree_calls,
          _judge("poses[{}]", 1e-9, 1e-9, angles=2,
                 cause="compose x_v = x_u (+) z along each tree edge (inverse(z) when the edge points from v "
                       "to u), the tree's edge to each vertex being the first in edge order at the previous "
                       "depth")),
    check(ROTATIONS, "theta by the chordal relaxation", 4, _rotation_calls,
          _judge("theta[{}]", 1e-7, 1e-9, angles=Ellipsis,
                 cause="minimize sum_k w_k ||v_j - R(theta_ij) v_i||^2 over v = (cos, sin) of every pose but "
                       "the anchor, w_k = information[k, 2, 2], then theta = atan2(s, c)")),
    check(TRANSLATIONS, "positions given the rotations", 4, _translation_calls,
          _judge("t[{}]", 1e-7, 1e-9,
                 cause="minimize sum_k r^T W r with r = t_j - t_i - R(theta_i) t_ij and W = R Omega_tt R^T, "
                       "R = R(theta_i + theta_ij)")),
]


_TARGETS = tuple(f"initialisation:{name.split('.')[1]}" for name in (TREE, ROTATIONS, TRANSLATIONS))


def _edges_of(call):
    return np.asarray(call.args[1]), np.asarray(call.args[2])


def _has_branch(call):
    """Whether the breadth-first tree from the anchor has a vertex with two children or more."""
    n, (ei, ej), anchor = call.args[0], _edges_of(call), call.kwargs.get("anchor", 0)
    depth, frontier, children = {anchor: 0}, [anchor], {}
    while frontier:
        nxt = []
        for u in frontier:
            for k in range(len(ei)):
                for a, b in ((ei[k], ej[k]), (ej[k], ei[k])):
                    if a == u and b not in depth:
                        depth[int(b)] = depth[u] + 1
                        children[u] = children.get(u, 0) + 1
                        nxt.append(int(b))
        frontier = nxt
    return len(depth) == n and max(children.values(), default=0) >= 2


def _parallel_at_anchor(call):
    (ei, ej), anchor = _edges_of(call), call.kwargs.get("anchor", 0)
    ends = [int(j) if i == anchor else int(i) for i, j in zip(ei, ej) if anchor in (i, j)]
    return len(ends) > len(set(ends))


def _translation_diagonal_anisotropic(call):
    tt = np.asarray(call.args[4])[:, :2, :2]
    diagonal = not np.any(tt[:, 0, 1]) and not np.any(tt[:, 1, 0])
    return len(tt) > 0 and diagonal and bool(np.any(tt[:, 0, 0] != tt[:, 1, 1]))


def _each(name, holds, targets=_TARGETS):
    return tuple(Edge(f"{target.split(':')[1]}: {name}", target, holds) for target in targets)


EDGES = (
    *_each("a single pose with no edge (N = 1, M = 0)", lambda call: call.args[0] == 1),
    *_each("two poses joined by one edge written from pose 1 to pose 0 (M = 1)",
           lambda call: call.args[0] == 2 and len(call.args[1]) == 1 and call.args[1][0] == 1),
    Edge("spanning_tree_poses: a spanning tree with a branch (a vertex with two children)", _TARGETS[0], _has_branch),
    *_each("two edges between the anchor and the same pose", _parallel_at_anchor, _TARGETS[1:]),
    Edge("chordal_translations: translation information diagonal but anisotropic", _TARGETS[2],
         _translation_diagonal_anisotropic),
    Edge("chordal_translations: translation information a multiple of the identity", _TARGETS[2],
         lambda call: bool(np.all(np.asarray(call.args[4])[:, :2, :2] == np.asarray(call.args[4])[:, :1, :1]
                                  * np.eye(2))) and len(call.args[1]) > 0),
)
