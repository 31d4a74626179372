"""The smoother's nonlinear factors and their linearisations at the linearisation point.

Each factor ``i`` has a type (``course.factorgraph.FactorType``), its variables ``keys[i]`` (the smoother's
variable indices, one per slot), a measurement and a whitening ``W`` (m, m) (``L^T`` of its information,
``course.factorgraph.noise.whitening``; None for unit information). Its linearisation at the variables'
linearisation points ``theta`` is kept (the cache the re-elimination reads)::

    ||W r(theta (+) delta)||^2  ~  ||A delta_keys - b||^2,    A = [W J_1 ... W J_s] (m, sum d_a),  b = -W r

stored as the blocks ``A_a`` (m, d_a) and ``b`` (m,). The Jacobians come from the implementation's Jets
(``jets.Jet``, ``autodiff_factor.tangent_jacobians``); the factors of one type linearised in one step are
evaluated together, vectorised.
"""

from dataclasses import dataclass, field

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import NonFiniteError


@dataclass
class TypeStore:
    """The factors of one type: their ids (indices into the store), measurements and whitenings."""

    type: object
    ids: list = field(default_factory=list)
    z: list = field(default_factory=list)
    W: list = field(default_factory=list)


class FactorStore:
    """Every factor the smoother holds, by id (in the order added), and its cached linearisation."""

    def __init__(self, impl="solutions"):
        self.impl = impl_loader.load(impl)
        self.types: dict = {}  # type name -> TypeStore
        self.type_of: list = []  # id -> (type name, row in its TypeStore)
        self.keys: list = []  # id -> tuple of variable indices
        self.A: list = []  # id -> [A_a (m, d_a)], the whitened Jacobian blocks at the linearisation point
        self.b: list = []  # id -> (m,), minus the whitened residual there
        self.of_variable: list = []  # variable -> the ids of the factors on it

    def __len__(self) -> int:
        return len(self.keys)

    def add_variable(self) -> None:
        self.of_variable.append([])

    def add(self, ftype, keys, z, W) -> int:
        """Factor of ``ftype`` on ``keys`` (variable indices), measurement ``z``, whitening ``W``; its id."""
        store = self.types.setdefault(ftype.name, TypeStore(ftype))
        if store.type != ftype:
            raise ValueError(f"two factor types are named {ftype.name!r}: give each factor type a name of its own")
        i = len(self.keys)
        self.type_of.append((ftype.name, len(store.ids)))
        store.ids.append(i)
        store.z.append(np.asarray(z, dtype=float))
        store.W.append(W)
        self.keys.append(tuple(int(v) for v in keys))
        self.A.append(None)
        self.b.append(None)
        for v in dict.fromkeys(self.keys[i]):
            self.of_variable[v].append(i)
        return i

    def _by_type(self, ids) -> dict:
        out: dict = {}
        for i in ids:
            name, row = self.type_of[i]
            if name not in out:
                out[name] = ([], [])
            group, rows = out[name]
            group.append(i)
            rows.append(row)
        return out

    def linearise(self, ids, theta, kinds) -> None:
        """Linearise the factors ``ids`` at ``theta`` (a list of stored values by variable), one
        evaluation per factor type; the blocks and right-hand sides replace their cached ones."""
        jet = None
        for name, (group, rows) in self._by_type(ids).items():
            store = self.types[name]
            ftype = store.type
            if jet is None:
                jet = self.impl.module("jets").Jet
                tangent_jacobians = self.impl.module("autodiff_factor").tangent_jacobians
            z = np.stack([store.z[row] for row in rows])
            xs = [np.stack([theta[self.keys[i][a]] for i in group]) for a in range(len(ftype.kinds))]
            plus = [kind.plus_jacobian(x) for kind, x in zip(ftype.kinds, xs)]
            r, J = tangent_jacobians(lambda *points, z=z, ftype=ftype: ftype.residual(z, *points), plus, xs, jet)
            r = np.asarray(r, dtype=float)
            J = [np.asarray(block, dtype=float) for block in J]
            if not (np.isfinite(r).all() and all(np.isfinite(block).all() for block in J)):
                bad = int(np.flatnonzero(~np.isfinite(r).all(axis=1) | ~np.all(
                    [np.isfinite(block).all(axis=(1, 2)) for block in J], axis=0))[0])
                raise NonFiniteError(f"the residual or Jacobian of factor {group[bad]} ({name}) is not finite at "
                                     "the linearisation point")
            Ws = [store.W[row] for row in rows]
            if any(W is not None for W in Ws):
                W = np.stack([np.eye(ftype.dim) if W is None else W for W in Ws])
                r = np.einsum("mab,mb->ma", W, r)
                J = [np.matmul(W, block) for block in J]
            for i, rhs, *blocks in zip(group, -r, *J):  # each factor's rows of the stacked arrays
                self.A[i] = blocks
                self.b[i] = rhs

    def chi2(self, theta) -> float:
        """``sum |W r|^2`` over every factor at the values ``theta`` (a list of stored values by variable)."""
        total = 0.0
        for store in self.types.values():
            ftype = store.type
            z = np.stack(store.z)
            xs = [np.stack([theta[self.keys[i][a]] for i in store.ids]) for a in range(len(ftype.kinds))]
            r = np.asarray(ftype.residual(z, *xs), dtype=float)
            if any(W is not None for W in store.W):
                W = np.stack([np.eye(ftype.dim) if W is None else W for W in store.W])
                r = np.einsum("mab,mb->ma", W, r)
            total += float(np.vdot(r, r))
        return total
