"""Chapter 8's incremental smoother: iSAM2 on the chapter-7 factor graph.

The pieces, one concept per file: the smoother's nonlinear factors and their cached linearisations
(``factors``), the numeric Bayes tree (``bayes_tree``: cliques with their conditional ``(R, S, d)`` and
cached factor on the separator), the
re-elimination of an affected top (``reelimination``), the wildfire update in fronts (``wildfire``), and the
smoother itself (``smoother``: ``update(new_factors, new_values)``, ``estimate()``, ``marginal``). Every
piece an exercise computes comes from the implementation (``course.core.impl.load(impl)``): the
elimination of a clique (or of a group of cliques at once), the ordering, the symbolic elimination, the
Bayes tree's structure, the fluid relinearisation, the affected top, the orphans' parents and the
wildfire update.
"""

from course.incremental.smoother import IncrementalSmoother, UpdateResult

__all__ = ["IncrementalSmoother", "UpdateResult"]
