"""A factor graph: variables keyed by name, and factors grouped by type.

    graph = FactorGraph("two poses")
    graph.add_variable("x0", SE2, [0, 0, 0])
    graph.add_variable("x1", SE2, [1, 0, 0.1])
    graph.fix("x0")
    graph.add(BETWEEN_SE2, ["x0", "x1"], [1, 0, 0], information=np.eye(3))

Variables are numbered in the order they are added; that is the order of their steps in H.
Factors of one type are kept together (a group), so that a linearisation evaluates each group
at once, vectorised over its factors; ``add_many`` adds a whole group.
"""

from dataclasses import dataclass, field

import numpy as np

from course.factorgraph.factor_type import FactorType
from course.solver.robust import RobustLoss


def symbol(letter: str, index: int) -> str:
    """The key ``"x12"`` of ``symbol("x", 12)`` (GTSAM's ``Symbol('x', 12)``, written as text)."""
    return f"{letter}{int(index)}"


@dataclass
class FactorGroup:
    """M factors of one type and one loss: ``keys`` (M, s) variable indices, ``measurements`` (M, ...),
    ``information`` (M, dim, dim) or None (unit); ``loss`` None (least squares) or a
    :class:`course.solver.robust.RobustLoss` on each factor's whitened ``s = |r|^2``."""

    type: FactorType
    loss: RobustLoss | None = None
    keys: list = field(default_factory=list)
    measurements: list = field(default_factory=list)
    information: list = field(default_factory=list)

    def arrays(self):
        """``(keys (M, s) int, z (M, ...), information (M, dim, dim) or None)``."""
        keys = np.concatenate([np.atleast_2d(k) for k in self.keys]).astype(np.int64)
        z = np.concatenate(self.measurements)
        info = None if all(i is None for i in self.information) else np.concatenate(
            [np.broadcast_to(np.eye(self.type.dim), (len(k), self.type.dim, self.type.dim)) if i is None else i
             for k, i in zip(self.keys, self.information)])
        return keys, z, info


class FactorGraph:
    """Variables (``add_variable``), factors (``add``, ``add_many``) and fixed variables or dofs (``fix``)."""

    def __init__(self, name: str = "factor graph"):
        self.name = name
        self.keys: list = []
        self.kinds: list = []
        self.values: list = []
        self.index: dict = {}
        self.groups: dict = {}
        self.fixed: list = []  # the variables held whole
        self.fixed_dofs: dict = {}  # variable index -> the tangent indices held (some, not all)

    @property
    def num_variables(self) -> int:
        return len(self.keys)

    @property
    def num_factors(self) -> int:
        return sum(sum(len(k) for k in g.keys) for g in self.groups.values())

    def add_variable(self, key, kind, value) -> int:
        """Add variable ``key`` of ``kind`` (``course.factorgraph.variables``) at ``value``; its index."""
        if key in self.index:
            raise ValueError(f"{self.name}: variable {key!r} is added twice")
        value = kind.check(value, f"{self.name}: variable {key!r}")
        self.index[key] = len(self.keys)
        self.keys.append(key)
        self.kinds.append(kind)
        self.values.append(value)
        return self.index[key]

    def fix(self, key, dofs=None) -> None:
        """Hold variable ``key`` at its value (its step is 0); with ``dofs`` (indices into its tangent
        step, ``0 .. dim - 1``), hold those alone and let the others move (Ceres' ``SubsetManifold``):
        ``graph.fix("c0", dofs=[0, 1, 2])`` holds an SE(3) pose's translation (ours is translation
        first). Fixing every dof is fixing the variable; fixing again adds to what is held."""
        v = self._variable(key, "fix")
        if dofs is None:
            self.fixed_dofs.pop(v, None)
            if v not in self.fixed:
                self.fixed.append(v)
            return
        dim = self.kinds[v].dim
        where = f"{self.name}: fix({key!r}, dofs={dofs!r})"
        held = np.asarray(dofs)
        if held.ndim != 1 or not len(held) or not np.issubdtype(held.dtype, np.integer):
            raise ValueError(f"{where}: dofs must be a non-empty list of integers (tangent indices)")
        if held.min() < 0 or held.max() >= dim:
            raise ValueError(f"{where}: a {self.kinds[v].name} variable has tangent indices 0 to {dim - 1}")
        if v in self.fixed:
            return
        merged = tuple(sorted(set(self.fixed_dofs.get(v, ())) | {int(d) for d in held}))
        if len(merged) == dim:
            self.fixed_dofs.pop(v, None)
            self.fixed.append(v)
        else:
            self.fixed_dofs[v] = merged

    def add(self, factor_type: FactorType, keys, measurement, information=None, loss=None, noise=None) -> None:
        """One factor of ``factor_type`` on the variables ``keys`` (one per slot); its noise by
        ``information`` and ``loss``, or by a ``noise`` model (``course.factorgraph.noise``: ``sigmas``,
        ``isotropic``, ``covariance``, ``information``, each ``.robust(kernel, scale)``)."""
        information, loss = _noise(factor_type, information, loss, noise, self.name)
        z = np.asarray(measurement, dtype=float)[None]
        info = None if information is None else np.asarray(information, dtype=float)[None]
        self.add_many(factor_type, [keys], z, info, loss)

    def add_many(self, factor_type: FactorType, keys, measurements, information=None, loss=None,
                 noise=None) -> None:
        """M factors of ``factor_type``: ``keys`` (M, s) registered variable keys, or an integer array of
        variable indices (the order of ``add_variable``), ``measurements``
        (M, ...), ``information`` (M, dim, dim), (dim, dim) or None (unit); ``loss`` None or a robust
        loss such as ``("huber", 2.0)`` (chapter 4's kernels, on the whitened ``|r|^2`` of each factor);
        or ``noise``, a noise model in place of both (as in ``add``)."""
        information, loss = _noise(factor_type, information, loss, noise, self.name)
        where = f"{self.name}: {factor_type.name}"
        loss = RobustLoss.of(loss)
        indices = np.array([[self._variable(k, where) for k in row] for row in keys], dtype=np.int64) \
            if len(keys) and not isinstance(keys, np.ndarray) else np.asarray(keys, dtype=np.int64)
        if indices.ndim != 2 or indices.shape[1] != len(factor_type.kinds):
            raise ValueError(f"{where}: keys must be (M, {len(factor_type.kinds)}), got {indices.shape}")
        if indices.size and (indices.min() < 0 or indices.max() >= self.num_variables):
            bad = int(indices[(indices < 0) | (indices >= self.num_variables)][0])
            raise ValueError(f"{where}: no variable with index {bad} ({self.num_variables} variables)")
        for slot, kind in enumerate(factor_type.kinds):
            wrong = [self.keys[v] for v in indices[:, slot] if self.kinds[v] != kind]
            if wrong:
                raise ValueError(f"{where}: slot {slot} takes a {kind.name} variable; {wrong[0]!r} is a "
                                 f"{self.kinds[self.index[wrong[0]]].name}")
        z = np.asarray(measurements, dtype=float)
        if len(z) != len(indices):
            raise ValueError(f"{where}: {len(indices)} factors but {len(z)} measurements")
        info = None
        if information is not None:
            info = np.asarray(information, dtype=float)
            if info.shape == (factor_type.dim, factor_type.dim):
                info = np.broadcast_to(info, (len(indices),) + info.shape)
        name = factor_type.name if loss is None else f"{factor_type.name} {loss}"
        group = self.groups.setdefault(name, FactorGroup(factor_type, loss))
        if group.type != factor_type:
            raise ValueError(f"{where}: two factor types are named {factor_type.name!r} (residuals "
                             f"{_function_name(group.type.residual)} and {_function_name(factor_type.residual)}): "
                             "give each factor type a name of its own")
        group.keys.append(indices)
        group.measurements.append(z)
        group.information.append(info)

    def _variable(self, key, where) -> int:
        """The index of the registered variable ``key`` (a key is never taken as an index: ``add_many``
        takes an integer array of indices for that)."""
        try:
            return self.index[key]
        except KeyError:
            prefix = "" if where.startswith(f"{self.name}: ") else f"{self.name}: "
            raise ValueError(f"{prefix}{where}: no variable {key!r} "
                             "(keys are the names given to add_variable)") from None


def _function_name(function) -> str:
    return f"{getattr(function, '__module__', '?')}.{getattr(function, '__qualname__', repr(function))}"


def _noise(factor_type, information, loss, noise, name):
    """``(information, loss)`` of a factor given either or a ``noise`` model."""
    if noise is None:
        return information, loss
    if information is not None or loss is not None:
        raise ValueError(f"{name}: {factor_type.name}: give noise= or information= and loss=, not both")
    if not hasattr(noise, "information") or not hasattr(noise, "loss"):
        raise ValueError(f"{name}: {factor_type.name}: noise must be a course.factorgraph.noise model "
                         f"(sigmas, isotropic, covariance, information), got {type(noise).__name__}")
    if noise.information.shape[-1] != factor_type.dim:
        raise ValueError(f"{name}: {factor_type.name}: a noise model of size {noise.information.shape[-1]} for "
                         f"a residual of size {factor_type.dim}")
    return noise.information, noise.loss
