"""A whole factor graph fed to a smoother one variable at a time, as a robot would see it.

Step ``k`` brings variable ``k`` (the order the graph's variables were added: a pose graph's odometry
order) and every factor whose last variable is ``k``: the odometry edge to ``k - 1`` and the loop
closures to earlier variables, as they arrive. Its initial value composes the factor to ``k - 1`` (a
between factor of its kind, either way round) onto the smoother's current estimate of ``k - 1``; where there is none,
the graph's own value. Step 0 also brings a prior on variable 0 (the graph's fixed variable becomes an
anchor the smoothers take: ``prior_sigma`` on every tangent entry).
"""

import numpy as np

from course.geometry import se2


def compose(kind, value, z) -> np.ndarray:
    """``value`` composed with the between measurement ``z`` (the value ``x_j`` with ``x_i^-1 x_j = z``)."""
    if kind.name == "SE2":
        return np.asarray(se2.compose(np.asarray(value)[None], np.asarray(z)[None])[0], dtype=float)
    if kind.name == "SE3":
        t, R = value[:3], value[3:].reshape(3, 3)
        tz, Rz = z[:3], z[3:].reshape(3, 3)
        return np.concatenate([t + R @ tz, (R @ Rz).ravel()])
    if kind.name.startswith("Vector"):
        return np.asarray(value, dtype=float) + z
    raise ValueError(f"no composition for a {kind.name} variable")


def inverse(kind, z) -> np.ndarray:
    """The between measurement ``z`` reversed (``x_j^-1 x_i`` from ``x_i^-1 x_j``)."""
    if kind.name == "SE2":
        c, s = np.cos(z[2]), np.sin(z[2])
        return np.array([-c * z[0] - s * z[1], s * z[0] - c * z[1], -z[2]])
    if kind.name == "SE3":
        R = z[3:].reshape(3, 3)
        return np.concatenate([-R.T @ z[:3], R.T.ravel()])
    raise ValueError(f"no inverse for a {kind.name} measurement")


class OnlineSequence:
    """The steps of ``graph`` (a chapter-7 ``FactorGraph``): ``len(seq)`` steps, ``seq.step(k, estimate)``."""

    def __init__(self, graph, prior_sigma: float = 1e-3):
        from course.factorgraph import between  # chapter 7's (imported where used: this package loads in any tree)

        self.graph = graph
        self.prior_sigma = float(prior_sigma)
        n = graph.num_variables
        self._rows: list = [[] for _ in range(n)]  # step -> [(group name, keys (s,), z, info or None)]
        self._odometry: list = [None] * n  # step -> the between measurement from k - 1, if any
        for name, group in graph.groups.items():
            keys, z, info = group.arrays()
            last = keys.max(axis=1)
            for row in np.argsort(last, kind="stable"):
                k = int(last[row])
                self._rows[k].append((name, keys[row], z[row], None if info is None else info[row]))
                kind = group.type.kinds[0]
                if kind.name in ("SE2", "SE3") and group.type == between(kind) and self._odometry[k] is None \
                        and {int(keys[row, 0]), int(keys[row, 1])} == {k - 1, k}:
                    # an edge from k to k - 1 (intel's order) measures the inverse
                    self._odometry[k] = z[row] if keys[row, 1] == k else inverse(kind, z[row])

    def __len__(self) -> int:
        return self.graph.num_variables

    def initial_value(self, k: int, previous) -> np.ndarray:
        """Variable k's initial value: the odometry composed onto ``previous`` (the estimate of k - 1)."""
        kind = self.graph.kinds[k]
        if k == 0 or self._odometry[k] is None or previous is None:
            return np.asarray(self.graph.values[k], dtype=float)
        return compose(kind, previous, self._odometry[k])

    def step(self, k: int, previous=None) -> tuple:
        """``(factors, new_values)``: a ``FactorGraph`` of step k's factors and ``{key_k: initial value}``."""
        from course.factorgraph import FactorGraph, prior

        g = self.graph
        out = FactorGraph(f"{g.name} step {k}")
        value = self.initial_value(k, previous)
        used = sorted({int(v) for _, keys, _, _ in self._rows[k] for v in keys} | {k})
        for v in used:
            out.add_variable(g.keys[v], g.kinds[v], value if v == k else g.values[v])
        if k == 0:
            kind = g.kinds[0]
            out.add(prior(kind), [g.keys[0]], np.asarray(g.values[0], dtype=float),
                    information=np.eye(kind.dim) / self.prior_sigma**2)
        for name, keys, z, info in self._rows[k]:
            out.add(g.groups[name].type, [g.keys[v] for v in keys], z, information=info)
        return out, {g.keys[k]: value}

    def edges(self, k: int) -> list:
        """Step k's factors as ``(group name, keys (s,), z, information or None)``."""
        return self._rows[k]
