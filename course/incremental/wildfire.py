"""The wildfire update of a large tree, fed to the implementation's ``wildfire_update`` front by front.

``wildfire_update`` takes a whole tree (its cliques numbered 0..C-1, its variables 0..n-1) and visits, from
the roots, the cliques that are replaced or whose separator changed, skipping any other clique's subtree.
After an update it can only reach the re-eliminated top and what hangs below it, and most updates stop
one level under the top: handing it the whole tree every time costs a pass over every clique. So the
tree is handed over in fronts, each a small tree of the same contract, with the same answer:

1. the first front: the replaced cliques (a top, closed under parents: its roots are roots; each group of
   them eliminated in one call handed as one clique with the group's conditional, which solves the same
   steps, up to rounding, for fewer cliques) and the cliques not replaced down to ``DEPTH`` levels below
   them (the candidates);
2. a later front: the candidates of the deepest level the previous front recomputed (the frontier: solved
   again, marked replaced, which gives the same steps), the cliques down to twice the previous front's
   levels below them as the new candidates (a change that reached this far tends to go further: fewer
   calls, few candidates left unchanged), and one root clique holding the variables of the frontier's
   separators as its frontals with the conditional ``(R = I, S empty, d = their new steps)``, marked
   replaced: it reproduces those steps, and, given their steps before the update as ``delta``, marks
   changed exactly the ones the whole pass marks;
3. until a front recomputes no candidate.

Each front's variables are numbered 0..n'-1 for the call; a clique is recomputed by the whole pass
exactly when it is recomputed in its front.
"""

import numpy as np

#: the levels of candidates below the frontier in the first front (doubled in each later one)
DEPTH = 4


def wildfire_in_fronts(wildfire_update, tree, delta, replaced, threshold, dims, groups=()) -> tuple:
    """``(new delta (list of n arrays), recomputed cliques (sorted))``, as ``wildfire_update(tree.frontals,
    tree.separators, tree.parents, tree.conditionals, delta, replaced, threshold)`` on the whole tree.

    ``groups``: replaced cliques eliminated together, ``(cliques (the group's root first), frontals,
    separator, (R, S, d))`` (the root's separator; the conditional over the frontals in that order, which
    the cliques' own are blocks of): the first front takes each as one clique (the same steps up to rounding,
    for fewer cliques)."""
    unit = {c: g for g, group in enumerate(groups) for c in group[0]}
    children = tree.children
    up = np.asarray(tree.parents).tolist()
    is_replaced = set(replaced)
    new = list(delta)
    recomputed = list(replaced)
    frontier = list(replaced)
    solved_root: list = []  # the variables of the fake root (none for the first front)
    first = True
    depth = DEPTH
    while frontier:
        # the candidates: depth levels below the frontier; the next frontier is among the deepest
        candidates, level = [], frontier
        for _ in range(depth):
            level = [ch for c in level for ch in children[c] if ch not in is_replaced]
            candidates += level
        deepest = set(level)
        if not candidates and not first:
            break
        cliques = frontier + candidates
        # one entry per clique, or per group of replaced cliques in the first front
        entries = []  # (the cliques it stands for, frontals, separator, parent clique, conditional)
        taken: set = set()
        for c in cliques:
            g = unit.get(c) if first else None
            if g is None:
                entries.append(((c,), tree.frontals[c], tree.separators[c], up[c], tree.conditionals[c]))
            elif g not in taken:
                taken.add(g)
                members, F, S, conditional = groups[g]
                entries.append((members, F, S, up[members[0]], conditional))
        offset = 1 if solved_root else 0
        number = {c: k + offset for k, entry in enumerate(entries) for c in entry[0]}
        orphaned = 0 if solved_root else -1  # the parent of a clique whose parent is outside the front
        variables = solved_root + [v for entry in entries for v in entry[1]]
        local = {v: k for k, v in enumerate(variables)}
        frontals: list = []
        separators: list = []
        parents: list = []
        conditionals: list = []
        if solved_root:
            frontals.append(list(range(len(solved_root))))
            separators.append([])
            parents.append(-1)
            f = sum(dims[v] for v in solved_root)
            conditionals.append((np.eye(f), np.zeros((f, 0)), np.concatenate([new[v] for v in solved_root])))
        start = len(solved_root)  # each entry's frontals are the next variables
        for _, F, S, p, conditional in entries:
            frontals.append(list(range(start, start + len(F))))
            start += len(F)
            separators.append([local[v] for v in S])
            parents.append(number.get(p, orphaned) if p >= 0 else -1)
            conditionals.append(conditional)
        marked = ([0] if solved_root else []) + sorted({number[c] for c in frontier})
        steps, done = wildfire_update(frontals, separators, np.array(parents, dtype=int), conditionals,
                                      [delta[v] for v in variables], marked, threshold)
        done = set(int(c) for c in done)
        for k, (_, F, _, _, _) in enumerate(entries):
            if k + offset in done:
                for v in F:
                    new[v] = np.asarray(steps[local[v]], dtype=float)
        recomputed += [c for c in candidates if number[c] in done]
        frontier = [c for c in candidates if number[c] in done and c in deepest]
        solved_root = list(dict.fromkeys(v for c in frontier for v in tree.separators[c]))
        first = False
        depth *= 2  # a change that reached this far tends to go further: fewer, larger fronts
    return new, sorted(recomputed)
