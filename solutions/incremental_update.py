"""Chapter 8: the incremental update of a Bayes tree (iSAM2: Kaess et al., IJRR 2012, Algorithms 4-7).

A smoother keeps the Bayes tree of its linearised problem: cliques numbered 0..C-1, clique c holding
its frontal variables ``frontals[c]``, its separator ``clique_separators[c]``, its parent
``parents[c]`` (-1 for a root) and its Gaussian conditional ``p(F_c | S_c)``. The n variables are
0..n-1; every one is a frontal of exactly one clique. When new factors arrive, or the linearisation
point of some variables moves, only part of the tree changes:

1. **Fluid relinearisation.** ``delta`` holds the current solution of the linearised system, one
   (d_v,) tangent step per variable, taken at the variable's linearisation point. A variable whose
   step has grown past a threshold is relinearised: its linearisation point takes the step, and every
   factor touching it is linearised again.
2. **The affected top.** A new factor changes the conditional of the clique that holds its
   first-eliminated variable, and so every clique on the path from there to the root; a relinearised
   variable changes every factor on it, so every clique whose variables (frontals *or* separator)
   hold it, and again their paths to the root. These cliques, the *top*, are removed and their
   variables re-eliminated (with a new ordering) together with the new variables. The subtrees hanging
   below the top, rooted at the *orphans* (the children of top cliques that are not in the top), are
   kept whole: each one's summary on its separator (its cached factor) enters the re-elimination.
3. **Reattaching.** After the re-elimination each orphan hangs from the new clique that holds, as a
   frontal, its separator's first-eliminated variable in the new ordering.
4. **The partial state update (wildfire).** The new solution is back-substituted from the roots,
   parents before children: ``delta_F = R^-1 (d - S delta_S)`` for clique (R, S, d). A clique is
   recomputed when it was replaced (re-eliminated: its conditional is new) or when one of its separator
   variables' steps changed, in this pass, by more than a threshold (largest absolute entry). Any other
   clique keeps its variables' old steps. The replaced cliques are a top (with a clique, its parent), so
   a clique that is not recomputed has no child to recompute: the child is not replaced, and its
   separator lies within its parent's variables, none of which changed.

Conventions: a variable's "largest absolute entry" is ``max(abs(delta_v))``; both thresholds compare
strictly (``> threshold``). Lists of variables and of cliques are returned sorted ascending.

Inputs at the edges of the contract (each is a check input):
- relinearised_keys: threshold 0 (every step not exactly zero is marked)
- relinearised_keys: a step exactly at the threshold (not marked)
- affected_cliques: a relinearised variable held in a separator (the clique holding it there is marked too)
- affected_cliques: new keys of variables not yet in the tree (ignored: they join the top)
- affected_cliques: two roots, one untouched
- affected_cliques: nothing new and nothing relinearised (an empty top)
- orphan_parents: a separator whose first-eliminated member in the new ordering is not its smallest index
- wildfire_update: a change below the threshold stops the update (the subtree keeps its steps)
- wildfire_update: threshold 0 and every clique replaced (the full back-substitution)
- wildfire_update: variables of sizes 1, 3 and 6 mixed

Allowed imports: numpy, scipy, course.core.errors.
"""

import itertools

import numpy as np
import scipy.linalg.lapack

from course.core.errors import ShapeError, SingularSystemError


def _tree(frontals, clique_separators, parents):
    """``(parents as an int array, n)`` or a ``ValueError`` naming the argument and the entry."""
    parents = np.asarray(parents)
    C = len(frontals)
    if len(clique_separators) != C or parents.shape != (C,):
        raise ValueError(f"frontals, clique_separators and parents must describe the same cliques: got {C}, "
                         f"{len(clique_separators)} and parents of shape {parents.shape}")
    if C and not np.issubdtype(parents.dtype, np.integer):
        raise ValueError(f"parents must hold ints, got dtype {parents.dtype}")
    bad = np.flatnonzero((parents < -1) | (parents >= C))
    if bad.size:
        raise ValueError(f"parents[{bad[0]}] = {parents[bad[0]]} is not a clique (0..{C - 1}) or -1 for a root")
    flat = np.fromiter(itertools.chain.from_iterable(frontals), dtype=np.int64)
    n = len(flat)
    if n and (flat.min() < 0 or flat.max() >= n or np.bincount(flat, minlength=n).max() > 1):
        seen = sorted(flat.tolist())
        raise ValueError(f"frontals must hold every variable of 0..{n - 1} exactly once, got {seen}")
    members = np.fromiter(itertools.chain.from_iterable(clique_separators), dtype=np.int64)
    if members.size and (members.min() < 0 or members.max() >= n):
        for c, S in enumerate(clique_separators):
            for j, v in enumerate(S):
                if not 0 <= int(v) < n:
                    raise ValueError(f"clique_separators[{c}][{j}] = {v} is not a variable of the tree (0..{n - 1})")
    parents = parents.astype(int)
    if (parents < np.arange(C)).all():
        return parents, n  # every parent numbered below its child: no cycle
    # a forest: every clique's 2^k-th ancestor is -1 once 2^k >= C (pointer doubling); else walk to name a cycle
    ancestor = parents.copy()
    for _ in range(int(C).bit_length()):
        ancestor = np.where(ancestor >= 0, ancestor[ancestor], -1)
    if not np.any(ancestor >= 0):
        return parents, n
    state = np.zeros(C, dtype=int)  # 0 not seen, 1 on the current walk up, 2 reaches a root
    for start in range(C):
        path, c = [], start
        while c != -1 and state[c] == 0:
            state[c] = 1
            path.append(c)
            c = int(parents[c])
        if c != -1 and state[c] == 1:
            raise ValueError(f"parents must describe a forest: clique {c} is its own ancestor")
        state[path] = 2
    return parents, n


def _shape(block) -> tuple:
    """``np.shape(block)``, read directly from an array (without np.shape's dispatch: a check per clique)."""
    return block.shape if isinstance(block, np.ndarray) else np.shape(block)


def relinearised_keys(delta, threshold):
    """Fluid relinearisation: the variables v with ``max(abs(delta[v])) > threshold``, sorted.

    Args: ``delta`` a list of n arrays (d_v,), each variable's current step; ``threshold`` a float >= 0.
    Returns a sorted list of ints. ValueError for a negative threshold or a step that is not finite.
    """
    if not threshold >= 0:
        raise ValueError(f"threshold must be >= 0, got {threshold!r}")
    steps = [np.asarray(step, dtype=float) for step in delta]
    flat = np.concatenate([step.ravel() for step in steps]) if steps else np.zeros(0)  # every entry, in order
    # one test for all steps; the loop only to name the first bad one
    if not np.isfinite(flat).all():
        for v, step in enumerate(steps):
            if not np.all(np.isfinite(step)):
                raise ValueError(f"delta[{v}] has entries that are not finite")
    # BEGIN SOLUTION
    # every entry compared at once (not one reduction per variable): a variable is marked by any entry past it
    owner = np.repeat(np.arange(len(steps)), [step.size for step in steps])  # the variable of each entry
    return np.unique(owner[np.abs(flat) > threshold]).tolist()
    # END SOLUTION


def affected_cliques(frontals, clique_separators, parents, new_keys, relinearised):
    """The top an update removes, and the orphans it leaves.

    Args: the tree (``frontals``, ``clique_separators``: lists of C lists of ints; ``parents`` (C,) ints, -1
    for a root); ``new_keys`` the variables the new factors touch (those >= n, not yet in the tree, are
    ignored: they join the top); ``relinearised`` the relinearised variables (all in the tree).
    Marked: a clique holding a new key as a frontal, and a clique whose frontals or separator hold a
    relinearised variable. Returns ``(top, orphans)``: sorted lists of cliques, ``top`` the marked cliques
    and all their ancestors, ``orphans`` the cliques outside the top whose parent is in it.
    ValueError for a negative key or a relinearised variable that is not in the tree.
    """
    parents, n = _tree(frontals, clique_separators, parents)
    new_keys, relinearised = [int(k) for k in new_keys], [int(k) for k in relinearised]
    for name, keys in (("new_keys", new_keys), ("relinearised", relinearised)):
        for i, k in enumerate(keys):
            if k < 0 or (name == "relinearised" and k >= n):
                raise ValueError(f"{name}[{i}] = {k} is not a variable of the tree (0..{n - 1})")
    # BEGIN SOLUTION
    C = len(frontals)
    home = np.empty(n, dtype=int)  # the clique holding each variable as a frontal
    home[np.fromiter(itertools.chain.from_iterable(frontals), dtype=int, count=n)] = np.repeat(
        np.arange(C), list(map(len, frontals)))
    marked = set(home[[k for k in new_keys if k < n]].tolist())
    if relinearised:
        # a clique holding a relinearised variable: as a frontal (its home) or in its separator
        relin = set(relinearised)
        marked |= set(home[relinearised].tolist())
        marked |= {c for c, S in enumerate(clique_separators) if not relin.isdisjoint(S)}
    up = parents.tolist()
    top: set = set()
    for c in marked:
        while c != -1 and c not in top:
            top.add(c)
            c = up[c]
    in_top = np.zeros(C + 1, dtype=bool)  # the last entry, False, stands for a root's parent -1
    in_top[list(top)] = True
    orphans = np.flatnonzero(~in_top[:C] & in_top[parents])
    return sorted(top), orphans.tolist()
    # END SOLUTION


def orphan_parents(orphan_separators, ordering, new_frontals):
    """Each orphan's parent in the re-eliminated top.

    Args: ``orphan_separators`` a list of the orphans' separators (lists of ints, none empty; their members
    are variables of the top); ``ordering`` the top's new elimination order (a list of its variables,
    the first eliminated first); ``new_frontals`` the new top's cliques' frontals (a list of lists).
    Returns (number of orphans,) ints: for each orphan the index, in ``new_frontals``, of the clique that
    holds as a frontal its separator's member eliminated first in ``ordering``. ValueError for an empty
    separator or a member that is not in ``ordering``.
    """
    order = [int(v) for v in ordering]
    position = {v: k for k, v in enumerate(order)}
    if len(position) != len(order):
        raise ValueError(f"ordering must not repeat a variable, got {order}")
    home = {}
    for c, F in enumerate(new_frontals):
        for j, v in enumerate(F):
            if int(v) not in position or int(v) in home:
                raise ValueError(f"new_frontals[{c}][{j}] = {v} is not a variable of the ordering, or is a frontal "
                                 "of two cliques")
            home[int(v)] = c
    if len(home) != len(order):
        raise ValueError(f"new_frontals must hold every variable of the ordering as a frontal, missing "
                         f"{sorted(set(order) - set(home))}")
    for i, S in enumerate(orphan_separators):
        if len(S) == 0:
            raise ValueError(f"orphan_separators[{i}] is empty: an orphan hangs from the top through its separator")
        for j, v in enumerate(S):
            if int(v) not in position:
                raise ValueError(f"orphan_separators[{i}][{j}] = {v} is not in the new ordering of the top")
    # BEGIN SOLUTION
    out = [home[min((int(v) for v in S), key=position.__getitem__)] for S in orphan_separators]
    return np.array(out, dtype=int)
    # END SOLUTION


def wildfire_update(frontals, clique_separators, parents, conditionals, delta, replaced, threshold):
    """The partial state update: back-substitution from the roots that stops where nothing changed.

    Args: the tree (as in :func:`affected_cliques`); ``conditionals`` a list of C triples ``(R, S, d)``:
    ``R`` (f, f) upper triangular over the clique's frontals stacked in the order of ``frontals[c]``, ``S``
    (f, s) over its separator stacked in the order of ``clique_separators[c]``, ``d`` (f,); ``delta`` the n
    steps before the update, a list of (d_v,) arrays (the sizes d_v are read from it); ``replaced`` the
    re-eliminated cliques, closed upwards (with a clique, its parent: the top of the tree); ``threshold`` >= 0.
    A clique is recomputed, ``delta_F = R^-1 (d - S delta_S)``, when it is in ``replaced`` or a separator
    variable's step changed in this pass by more than ``threshold`` (largest absolute entry); parents are
    visited before children. Returns ``(new_delta, recomputed)``: a new list of n arrays (``delta`` is not
    modified) and the sorted list of recomputed cliques. ShapeError (a ValueError) for blocks of the wrong shape,
    SingularSystemError for a zero on R's diagonal, ValueError for a ``replaced`` that is not the top of the
    tree or a tree that is not one.
    """
    parents, n = _tree(frontals, clique_separators, parents)
    if len(delta) != n:
        raise ValueError(f"delta must hold one step per variable ({n}), got {len(delta)}")
    old = [np.asarray(step, dtype=float) for step in delta]
    # one test for all steps; the loop only to name the first bad one
    if any(step.ndim != 1 for step in old) or not np.isfinite(np.concatenate(old) if old else 0.0).all():
        for v, step in enumerate(old):
            if step.ndim != 1 or not np.all(np.isfinite(step)):
                raise ValueError(f"delta[{v}] must be a finite 1-D step (d_v,), got shape {step.shape}")
    if len(conditionals) != len(frontals):
        raise ValueError(f"conditionals must hold one (R, S, d) per clique ({len(frontals)}), got {len(conditionals)}")
    sizes = [step.size for step in old]
    # one test for all cliques (every block's shape, R's diagonals concatenated); the loop only to name the first
    # bad one
    f_of = [sum(map(sizes.__getitem__, F)) for F in frontals]
    s_of = [sum(map(sizes.__getitem__, S)) for S in clique_separators]
    shapes = [(_shape(R), _shape(S), _shape(d)) for R, S, d in conditionals]
    if shapes != [((f, f), (f, s), (f,)) for f, s in zip(f_of, s_of)] or (
            conditionals and not np.concatenate([np.asarray(R).diagonal() for R, _, _ in conditionals]).all()):
        for c, (R, S, d) in enumerate(conditionals):
            f, s = f_of[c], s_of[c]
            for name, block, shape in (("R", R, (f, f)), ("S", S, (f, s)), ("d", d, (f,))):
                if np.shape(block) != shape:
                    raise ShapeError(f"conditionals[{c}]: {name} has shape {np.shape(block)}, expected {shape} "
                                     f"(clique {c}'s frontals {list(frontals[c])}, separator "
                                     f"{list(clique_separators[c])})")
            diagonal = np.asarray(R, dtype=float).diagonal()
            if not diagonal.all():
                zero = np.flatnonzero(diagonal == 0.0)
                raise SingularSystemError(f"conditionals[{c}]: R[{zero[0]}, {zero[0]}] is 0, R is singular")
    if not threshold >= 0:
        raise ValueError(f"threshold must be >= 0, got {threshold!r}")
    for i, c in enumerate(replaced):
        if not 0 <= int(c) < len(frontals):
            raise ValueError(f"replaced[{i}] = {c} is not a clique (0..{len(frontals) - 1})")
    given = {int(c) for c in replaced}
    for c in sorted(given):
        if parents[c] != -1 and parents[c] not in given:
            raise ValueError(f"replaced must be closed upwards (the top of the tree): clique {c} is replaced, its "
                             f"parent {parents[c]} is not")
    # BEGIN SOLUTION
    new = list(old)  # a new list: the steps recomputed are new arrays, no array of delta is written into
    replaced = set(int(c) for c in replaced)
    children: list[list[int]] = [[] for _ in frontals]
    stack = []  # the roots first
    for c, p in enumerate(parents.tolist()):
        (stack if p == -1 else children[p]).append(c)
    changed: set = set()
    recomputed = []
    while stack:
        c = stack.pop()
        if c not in replaced and changed.isdisjoint(clique_separators[c]):
            continue  # nothing below can change: a child's separator lies within this clique's variables
        R, S, d = conditionals[c]
        s = np.concatenate([new[v] for v in clique_separators[c]]) if clique_separators[c] else np.zeros(0)
        # x = R^-1 (d - S s), by LAPACK's triangular solve (a tenth of solve_triangular's cost on small blocks)
        x = scipy.linalg.lapack.dtrtrs(np.asarray(R, dtype=float), d - np.asarray(S) @ s)[0] if len(d) else np.zeros(0)
        # the entries that moved past the threshold, the clique's all at once (not one reduction per variable)
        before = np.concatenate([old[v] for v in frontals[c]]) if frontals[c] else x
        moved = (np.abs(x - before) > threshold).tolist()
        start = 0
        for v in frontals[c]:
            stop = start + old[v].size
            if any(moved[start:stop]):  # the step's largest absolute change is past the threshold
                changed.add(v)
            new[v] = x[start:stop]
            start = stop
        recomputed.append(c)
        stack.extend(children[c])
    return new, sorted(recomputed)
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``)
HINTS = {
    "relinearised_keys": (
        """A variable's step is how far the linear solution wants to move it from the point its factors were
        linearised at; the linearisation is good while that step is small. Compare each step's largest entry.""",
        """v is relinearised exactly when max_i |delta_v[i]| > threshold: the infinity norm, not the Euclidean norm
        (a 6-vector with every entry just below the threshold is not marked).""",
        """[v for v, step in enumerate(delta) if np.max(np.abs(step)) > threshold].""",
    ),
    "affected_cliques": (
        """A clique's conditional summarises every factor whose first-eliminated variable is one of its frontals,
        and everything its subtree passed up. Ask which conditionals a new factor changes, and which a factor
        linearised again changes.""",
        """A new factor on keys K is eliminated with the first-eliminated of K, a frontal of some clique: that clique
        changes, and with it every clique on its path to the root (their cached factors change). A relinearised
        variable changes every factor on it: such a factor lives in a clique that holds the variable as a frontal
        or in its separator, so mark those too, then close upwards. Orphans: children of the top outside it.""",
        """marked = {clique_of[k] for k in new_keys if k < n} | {c for c if relinearised meets frontals[c] or
        clique_separators[c]}; top = marked and, for each, every parent up to -1; orphans = [c not in top with
        parents[c] in top]; return both sorted.""",
    ),
    "orphan_parents": (
        """An orphan is a conditional p(F | S) whose separator S now lies in the re-eliminated top. By the rule that
        built the tree, which clique does a conditional hang from?""",
        """Its parent is the clique holding S's first-eliminated member, first in the NEW ordering: the old
        ordering, and the smallest index, are not it.""",
        """With position = {v: k for k, v in enumerate(ordering)} and home = {v: c for c, F in enumerate(new_frontals)
        for v in F} (both built above): parent = home[min(S, key=position.get)] for each orphan's S.""",
    ),
    "wildfire_update": (
        """Back-substitution solves the cliques from the roots down: a clique needs only its separator's steps,
        which its ancestors have already fixed. Which cliques can give a new answer?""",
        """A replaced clique has a new conditional: solve it. Any other clique's conditional is the same, so its
        answer changes only if its separator's steps did: skip it when none of them changed by more than the
        threshold, and then skip its subtree too (its children's separators lie in its variables).""",
        """changed = set(); from the roots (a stack), for clique c: if c in replaced or changed meets S_c: x = solve(R,
        d - S @ concatenate(new[v] for v in S_c)); split x over F_c, adding to changed each v with
        max|x_v - old_v| > threshold; push c's children. Copy delta first; return it and the sorted recomputed.""",
    ),
}
