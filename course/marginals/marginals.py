"""Marginal covariances of a problem's variables at given values (chapter 8), as GTSAM's ``Marginals``.

``Marginals(problem, values)`` linearises the problem at ``values`` (typically the optimum of a solve),
takes H (``course.marginals.information``) without the dofs the problem holds still, orders its
variables by a fill-reducing ordering that keeps each variable's block together
(``course.marginals.ordering``), factorises ``H[p, p] = R^T R`` (``course.marginals.factorization``)
and hands R to the implementation's ``marginal_covariances`` (every variable's block of
``Sigma = H^-1`` by the recursion on R's pattern) and ``joint_marginal`` (triangular solves): in a
student's tree, the student's code, and an unwritten one a ``NotImplementedError`` naming its TODO.

The covariances are in the problem's tangent (``course.marginals.layouts``); a held dof's rows and
columns are 0. Keys are the layout's (pose indices for pose graphs, the graph's keys for a factor graph).
"""

import numpy as np
import scipy.sparse as sp

from course.core import impl as impl_loader
from course.core.errors import SingularSystemError
from course.marginals.factorization import square_root_information
from course.marginals.information import upper_of
from course.marginals.layouts import GaugeError, Layout, layout_of
from course.marginals.ordering import scalar_permutation, variable_graph, variable_order


class Marginals:
    """The marginals of one linearisation: ``covariance(key)`` (d, d), ``covariances(keys)`` {key: (d, d)},
    ``joint(keys)`` (sum d, sum d). R is factorised once, when made; every variable's block is computed
    by the first ``covariance`` or ``covariances`` and kept."""

    def __init__(self, problem, values, impl=None):
        """``problem`` of one of the course's families (``course.marginals.layouts``), linearised at
        ``values`` (its point ``x``); ``impl``: the implementation whose ``marginal_covariances`` runs
        (default: this tree's)."""
        layout = layout_of(problem)
        self._setup(upper_of(problem.linearize(np.asarray(values, dtype=float))), layout, impl)

    @classmethod
    def of_information(cls, H, sizes, keys=None, held=None, impl=None) -> "Marginals":
        """Marginals of an information matrix ``H`` (n, n) (dense or sparse; its upper triangle is read)
        whose variables have tangent ``sizes`` (m,); ``keys`` (default ``0..m-1``), ``held`` (n,) bool."""
        sizes = np.asarray(sizes, dtype=np.int64)
        n = H.shape[0]
        if H.shape != (n, n) or int(sizes.sum()) != n or (sizes < 1).any():
            raise ValueError(f"H must be (n, n) with n = sum(sizes) and every size >= 1: H is {H.shape}, "
                             f"sum(sizes) = {int(sizes.sum())}")
        keys = list(range(len(sizes))) if keys is None else list(keys)
        if len(keys) != len(sizes):
            raise ValueError(f"keys: {len(keys)} keys for {len(sizes)} variables")
        held = np.zeros(n, dtype=bool) if held is None else np.asarray(held, dtype=bool)
        upper = sp.csc_matrix(sp.triu(H if sp.issparse(H) else np.asarray(H, dtype=float)))
        self = cls.__new__(cls)
        self._setup(upper, Layout(keys, sizes, held, "H is singular"), impl)
        return self

    def _setup(self, H_upper, layout: Layout, impl) -> None:
        self.layout = layout
        self._module = impl_loader.load(impl or impl_loader.default_impl()).module("marginal_covariances")
        self._index = {key: v for v, key in enumerate(layout.keys)}
        if len(self._index) != len(layout.keys):
            raise ValueError("the layout's keys repeat")
        starts = layout.starts
        free = np.flatnonzero(~layout.held)
        owner = np.repeat(np.arange(len(layout.sizes)), layout.sizes)
        free_sizes = np.bincount(owner[free], minlength=len(layout.sizes))
        self._kept = np.flatnonzero(free_sizes > 0)  # variables with a free dof, in H's order
        kept_starts = np.concatenate([[0], np.cumsum(free_sizes[self._kept])]).astype(np.int64)
        # each variable's free dofs within its own tangent
        self._free_local = [np.flatnonzero(~layout.held[starts[v]:starts[v + 1]]) for v in range(len(layout.sizes))]
        H = H_upper[free][:, free] if len(free) < H_upper.shape[0] else H_upper
        self.order = variable_order(variable_graph(H, kept_starts))  # positions in _kept, R's order
        self._position = np.full(len(layout.sizes), -1)  # variable -> its place in R's order
        self._position[self._kept[self.order]] = np.arange(len(self.order))
        self.sizes = free_sizes[self._kept][self.order]  # R's variables' sizes
        try:
            self.R = square_root_information(H, kept_starts, scalar_permutation(self.order, kept_starts))
        except SingularSystemError as exc:
            raise SingularSystemError(f"H is not positive definite at these values: {layout.gauge} ({exc})") \
                from None
        self._blocks: list | None = None

    def _variable(self, key, where) -> int:
        try:
            return self._index[key]
        except (KeyError, TypeError):
            shown = self.layout.keys[:3]
            raise KeyError(f"{where}: {key!r} is not a variable of the problem (its keys: {', '.join(map(repr, shown))}"
                           f"{', ...' if len(self.layout.keys) > 3 else ''})") from None

    def _variables(self, keys, where) -> list:
        keys = list(self.layout.keys if keys is None else keys)
        if not keys:
            raise ValueError(f"{where}: no keys")
        seen: dict = {}
        for k, key in enumerate(keys):
            v = self._variable(key, where)
            if v in seen:
                raise ValueError(f"{where}: keys[{k}] = {key!r} repeats keys[{seen[v]}]: each variable once")
            seen[v] = k
        return list(seen)

    def _embed(self, v, block) -> np.ndarray:
        d = int(self.layout.sizes[v])
        local = self._free_local[v]
        if len(local) == d:
            return np.asarray(block)
        out = np.zeros((d, d))
        out[np.ix_(local, local)] = block
        return out

    def covariances(self, keys=None) -> dict:
        """``{key: Sigma_key (d, d)}`` for ``keys`` (default every variable), in the order given."""
        variables = self._variables(keys, "covariances")
        if self._blocks is None:
            self._blocks = list(self._module.marginal_covariances(self.R, self.sizes.tolist()))
            if len(self._blocks) != len(self.sizes):
                raise ValueError(f"marginal_covariances.marginal_covariances returned {len(self._blocks)} blocks "
                                 f"for {len(self.sizes)} variables")
        out = {}
        for v in variables:
            p = self._position[v]
            block = np.zeros((0, 0)) if p < 0 else np.asarray(self._blocks[p], dtype=float)
            out[self.layout.keys[v]] = self._embed(v, block)
        return out

    def covariance(self, key) -> np.ndarray:
        """``Sigma_key`` (d, d), d the variable's tangent size."""
        return self.covariances([key])[key]

    def joint(self, keys) -> np.ndarray:
        """The joint covariance of ``keys`` (sum d, sum d), in the order given, cross-covariances included."""
        variables = self._variables(keys, "joint")
        sizes = self.layout.sizes[variables]
        offsets = np.concatenate([[0], np.cumsum(sizes)])
        out = np.zeros((offsets[-1], offsets[-1]))
        free = [v for v in variables if self._position[v] >= 0]
        if not free:
            return out
        joint = np.asarray(self._module.joint_marginal(self.R, self.sizes.tolist(),
                                                       [int(self._position[v]) for v in free]), dtype=float)
        # the rows of each free variable's free dofs in the full (sum d) matrix
        where = np.concatenate([offsets[variables.index(v)] + self._free_local[v] for v in free])
        out[np.ix_(where, where)] = joint
        return out


def marginals(problem, values, keys=None, impl=None) -> dict:
    """``{key: Sigma_key (d, d)}`` of ``problem`` at ``values`` (:class:`Marginals`), keys default every
    variable."""
    return Marginals(problem, values, impl).covariances(keys)


def joint_marginal(problem, values, keys, impl=None) -> np.ndarray:
    """The joint covariance (sum d, sum d) of ``keys`` of ``problem`` at ``values`` (:class:`Marginals`)."""
    return Marginals(problem, values, impl).joint(keys)


__all__ = ["GaugeError", "Marginals", "joint_marginal", "marginals"]
