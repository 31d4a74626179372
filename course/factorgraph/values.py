"""A solution read by key: ``values["x3"]`` the typed value of variable ``x3`` (GTSAM's ``Values``).

    result = minimize(problem, "lm-type3")
    values = problem.values_of(result.params)
    values["x3"]            # SE2: array (3,); SO3: (3, 3); SE3: a Pose3 (t, R); Vector(n): (n,)
    values.array("x3")      # the stored value as it sits in x (SE3: (12,), t then R row by row)
"""

from collections.abc import Iterator, Mapping

import numpy as np


class Values(Mapping):
    """The variables of a factor graph at ``x``, by key, in the order they were added."""

    def __init__(self, graph, x, offsets):
        self._graph = graph
        self._x = np.array(x, dtype=float)
        self._offsets = offsets

    def array(self, key) -> np.ndarray:
        """The stored value of ``key`` (its kind's shape)."""
        v = self._index(key)
        kind = self._graph.kinds[v]
        return self._x[self._offsets[v]:self._offsets[v + 1]].reshape(kind.shape).copy()

    def __getitem__(self, key):
        return self._graph.kinds[self._index(key)].typed(self.array(key))

    def __iter__(self) -> Iterator:
        return iter(self._graph.keys)

    def __len__(self) -> int:
        return self._graph.num_variables

    def _index(self, key) -> int:
        try:
            return self._graph.index[key]
        except (KeyError, TypeError):
            raise KeyError(f"{self._graph.name}: no variable {key!r}") from None
