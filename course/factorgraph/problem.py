"""A factor graph as a problem of the one minimizer: ``x0``, ``chi2``, ``linearize``, ``solve``, ``retract``.

``x`` (n_x,) is every variable's stored value, one after the other in the order they were added;
a step ``h`` (n,) is every variable's tangent step in the same order. ``linearize`` evaluates each
group of factors at once: the values of its variables gathered, the residual and its tangent
Jacobians (``jacobians``: ``"autodiff"`` by the implementation's Jets and ``autodiff_factor``, each
variable's stored value seeded with its kind's ``plus_jacobian`` (found once per variable where its
factors outnumber its kind's variables, and gathered per factor), ``"numeric"`` by central
differences, or a function that a peer supplies, see ``FactorGraphProblem``; a fixed variable is not
differentiated: a constant, or its seed 0 in the factors that hold it, and its blocks 0 on every
path; the Jets evaluate a group in chunks that stay in the cache, one slot at a time, ``SLOT_BY_SLOT``),
whitened by the square root of the information (the Jets' output chunk by chunk, as it comes), and all
groups assembled by the implementation's ``factor_linearisation.BlockSparseAssembler`` into a pattern
found once. The
step comes from the sparse solve ``course.solver.choice`` picks (``solver``, default ``auto``: CHOLMOD
on a large system where cvxopt is installed, else the implementation's sparse Cholesky solver of
chapter 2, or SuperLU where qdldl is not installed; ``linear_solve`` names it; CHOLMOD analyses H's
pattern when the problem is made, ``course.solver.cholmod.analyse_ahead``); where one kind of
variable is never joined to another of its kind by a factor (the points of bundle adjustment, the
landmarks of SLAM), those are eliminated first (``course.factorgraph.schur_elimination``, chapter 4's
Schur complement for any graph).

A variable fixed whole is held by the assembly (the exercise's contract: its rows and columns of H
zero but for the identity, its entries of b zero). Some dofs of a variable (``graph.fix(key, dofs)``,
Ceres' ``SubsetManifold``) are held here, around it: their Jacobian columns are zeroed before the
assembly and 1 put on their diagonal after, so that their step is 0 and the others' are those of the
system without them. An eliminated variable may be partly fixed: its block of D then holds the
identity on the held dofs, decoupled from the rest, and their step comes out 0.
"""

from functools import partial

import numpy as np
import scipy.sparse as sp

from course.core import impl as impl_loader
from course.core.errors import NonFiniteError, ShapeError, SingularSystemError, check_array
from course.factorgraph import noise
from course.factorgraph.graph import FactorGraph
from course.factorgraph.numeric import central_differences
from course.factorgraph.schur_elimination import SchurElimination
from course.factorgraph.values import Values
from course.solver import robust
from course.solver.choice import choose
from course.solver.cholmod import analyse_ahead
from course.solver.held_still import check_held_still
from course.solver.linearization import Linearization
from course.solver.superlu import checked_step

JACOBIANS = ("autodiff", "numeric")
#: the bytes of one Jet's derivative per evaluation of the automatic Jacobians: a factor type's factors
#: are evaluated in chunks whose widest seeded value (M, n, k) holds about this many, so that a chunk's
#: Jets stay in the cache (ladybug-49's 31843 observations: 143 ms at once, 48 ms in chunks)
CHUNK_BYTES = 1 << 20
#: the fewest factors per chunk (below it the Python of each Jet operation costs more than its arithmetic)
CHUNK_MIN = 256
#: each free slot of a factor differentiated in an evaluation of its own, its Jets in that variable's
#: d_a directions alone (the other variables plain arrays): a product of two Jets of different variables
#: spends half its arithmetic on zeros, and a product with a constant is one term of the product rule. On
#: sphere2500's between factors two evaluations of 6 directions take 0.8 of one of 12.
SLOT_BY_SLOT = True


class FactorGraphProblem:
    """The minimizer's problem for ``graph``, with the Jacobians of ``jacobians`` and ``impl``'s pieces.

    ``jacobians`` is one of ``JACOBIANS``, or a function ``jacobians(factor_type, z, xs) -> (r (M, m),
    [J_a (M, m, d_a)])`` (``xs`` the values of the factors' variables, slot by slot, as
    ``factor_jacobians`` gathers them): the hook through which another automatic differentiation
    (``course.backends.factorgraph.jax_factors``) linearises the same graph for the same minimizer.
    The error (``chi2``) is always the factor types' own residual.

    ``eliminate``: ``"auto"`` eliminates the kind of variable that :func:`eliminated_kind` finds,
    ``None`` solves the whole H. ``solver``: a name of ``course.solver.choice.SOLVES`` (default
    ``auto``, decided on the size of the system solved after elimination) or an object with
    ``solve(H_upper, b) -> dx``.
    """

    def __init__(self, graph: FactorGraph, impl="solutions", jacobians="autodiff", solver=None, eliminate="auto"):
        if isinstance(jacobians, str) and jacobians not in JACOBIANS or \
                not isinstance(jacobians, str) and not callable(jacobians):
            raise ValueError(f"jacobians must be one of {JACOBIANS} or a function, got {jacobians!r}")
        self.graph = graph
        self.impl = impl_loader.load(impl)
        self.jacobians = jacobians
        kinds = graph.kinds
        sizes = np.array([int(np.prod(k.shape)) for k in kinds], dtype=np.int64)
        dims = np.array([k.dim for k in kinds], dtype=np.int64)
        self._x_offsets = np.concatenate([[0], np.cumsum(sizes)])
        self._h_offsets = np.concatenate([[0], np.cumsum(dims)])
        self.x0 = np.concatenate([v.ravel() for v in graph.values]) if graph.values else np.zeros(0)
        # per kind: its variables, and the index arrays that gather their values and steps
        self._by_kind = {}
        for kind in dict.fromkeys(kinds):
            members = np.array([v for v, k in enumerate(kinds) if k == kind], dtype=np.int64)
            size = int(np.prod(kind.shape))
            self._by_kind[kind] = (members, self._x_offsets[members][:, None] + np.arange(size),
                                   self._h_offsets[members][:, None] + np.arange(kind.dim))
        self._groups = [(group.type, *group.arrays()) for group in graph.groups.values()]
        # per group, per slot: the entries of x that hold its variables' values, and their shape
        self._gathers = [[(self._x_offsets[keys[:, a]][:, None] + np.arange(int(np.prod(kind.shape))),
                           (len(keys),) + kind.shape) for a, kind in enumerate(ftype.kinds)]
                         for ftype, keys, _, _ in self._groups]
        # per group, per slot: each factor's variable's row among its kind's (``_by_kind``), where the group
        # holds the kind at least as often as it has variables: its plus-Jacobians are then found once per
        # variable and gathered (each pose of a pose graph is in about 7 factors), else None
        rank = np.zeros(len(kinds), dtype=np.int64)
        for members, _, _ in self._by_kind.values():
            rank[members] = np.arange(len(members))
        self._plus_rows = [[rank[keys[:, a]] if sum(k == kind for k in ftype.kinds) * len(keys)
                            >= len(self._by_kind[kind][0]) else None for a, kind in enumerate(ftype.kinds)]
                           for ftype, keys, _, _ in self._groups]
        self._whitening = [noise.whitening(info, ftype.dim, len(keys), f"{graph.name}: {ftype.name}")
                           for ftype, keys, _, info in self._groups]
        self._diagonal = [noise.diagonal(W) for W in self._whitening]  # (M, m) where W is diagonal, else None
        self._losses = [group.loss for group in graph.groups.values()]
        self._kernels = self.impl.module("robust_kernels") if any(self._losses) else None
        self._fixed = np.array(sorted(set(graph.fixed)), dtype=np.int64)
        # per group, per slot: which factors hold a fixed variable there (None where none does)
        self._held = [[held if held.any() else None for held in np.isin(keys, self._fixed).T]
                      for _, keys, _, _ in self._groups]
        self._whole_fixed_dof = np.concatenate([np.arange(self._h_offsets[v], self._h_offsets[v + 1])
                                                for v in self._fixed]) if len(self._fixed) else np.zeros(0, np.int64)
        # the dofs held of partly fixed variables: their Jacobian columns zeroed, 1 on their diagonal
        self._partial_dof = np.array(sorted(int(self._h_offsets[v]) + d for v, held in graph.fixed_dofs.items()
                                            for d in held), dtype=np.int64)
        self._fixed_dof = np.union1d(self._whole_fixed_dof, self._partial_dof).astype(np.int64)
        self._column_masks = [_column_masks(ftype, keys, graph.fixed_dofs) for ftype, keys, _, _ in self._groups]
        self._assembler = self.impl.module("factor_linearisation").BlockSparseAssembler(
            dims, [keys for _, keys, _, _ in self._groups], self._fixed)
        self._held_checked = False
        if eliminate not in ("auto", None):
            raise ValueError(f"eliminate must be 'auto' or None, got {eliminate!r}")
        kind = eliminated_kind(graph) if eliminate == "auto" else None
        self.eliminated = kind
        solved = int(dims.sum()) - (0 if kind is None else int(dims[self._by_kind[kind][0]].sum()))
        self._solver, self.linear_solve = choose(solver, self.impl.module("sparse_solve"), solved)
        self._schur = None if kind is None else SchurElimination(
            dims, self._by_kind[kind][0], self._solver, graph.name, graph.keys)
        if self._schur is None:  # H's pattern is fixed: its ordering found now, not in a run
            analyse_ahead(self._solver, self._pattern)

    def _pattern(self):
        """An H of the assembler's pattern (upper triangle, CSC), from zero residuals and Jacobians."""
        H, _, _ = self._assembler.assemble([(np.zeros((len(keys), ftype.dim)),
                                             [np.zeros((len(keys), ftype.dim, kind.dim)) for kind in ftype.kinds])
                                            for ftype, keys, _, _ in self._groups])
        if len(self._partial_dof):
            H, _ = self._hold_partial(H, getattr(self._assembler, "diagonal_positions", None))
        return H

    # ------------------------------------------------------------ values

    def values(self, x, variables) -> np.ndarray:
        """The stored values (M, *shape) of ``variables`` (M,) (all of one kind) in ``x``."""
        kind = self.graph.kinds[int(variables[0])]
        size = int(np.prod(kind.shape))
        index = self._x_offsets[np.asarray(variables)][:, None] + np.arange(size)
        return np.asarray(x)[index].reshape((len(variables),) + kind.shape)

    def values_of(self, x) -> Values:
        """Every variable of ``x`` by key, typed (:class:`course.factorgraph.values.Values`)."""
        return Values(self.graph, x, self._x_offsets)

    def _slots(self, x, group: int):
        """The values of group ``group``'s variables at ``x``, slot by slot (M, *shape_a)."""
        x = np.asarray(x)
        return [np.take(x, index).reshape(shape) for index, shape in self._gathers[group]]

    def residuals(self, x) -> list:
        """Per group, the whitened residuals (M_g, m_g) at ``x``."""
        out = []
        for group, ((ftype, _, z, _), W) in enumerate(zip(self._groups, self._whitening)):
            r = np.asarray(ftype.residual(z, *self._slots(x, group)), dtype=float)
            out.append(noise.whiten(W, r, [], diagonal=self._diagonal[group])[0])
        return out

    def chi2(self, x) -> float:
        """``sum r^T r`` over the whitened residuals, ``sum rho(r^T r)`` in a group with a robust loss."""
        return float(sum(float(np.vdot(r, r)) if loss is None else robust.robust_chi2(self._kernels, loss, r)
                         for r, loss in zip(self.residuals(x), self._losses)))

    # ------------------------------------------------------------ the linearisation

    def factor_jacobians(self, x, group: int, plus_by_kind=None):
        """``(r (M, m), [J_a (M, m, d_a)])`` of group ``group`` at ``x``, before whitening.

        ``plus_by_kind``: a dict that keeps, per kind, the plus-Jacobians of all its variables at ``x`` once
        found (one linearisation's groups share it), or None."""
        ftype, keys, z, _ = self._groups[group]
        plus_by_kind = {} if plus_by_kind is None else plus_by_kind

        def residual(*points):
            return ftype.residual(z, *points)

        retractions = [kind.retract for kind in ftype.kinds]
        dims = [kind.dim for kind in ftype.kinds]
        xs = self._slots(x, group)
        held = self._held[group]
        if callable(self.jacobians):
            r, J = self.jacobians(ftype, z, xs)
            return self._checked(r, (len(keys), ftype.dim), "jacobians", "r", group, 0), self._held_still(held, [
                self._checked(block, (len(keys), ftype.dim, d), "jacobians", f"J[{a}]", group, 0)
                for a, (block, d) in enumerate(zip(J, dims))])
        if self.jacobians == "numeric":
            r, J = central_differences(residual, retractions, dims, xs)
            return self._checked(r, (len(keys), ftype.dim), "the residual", "r", group, 0), self._held_still(held, J)
        return self._autodiff(x, group, xs, plus_by_kind, whiten=False)

    def _autodiff(self, x, group: int, xs: list, plus_by_kind: dict, whiten: bool):
        """``factor_jacobians`` by the Jets, chunk by chunk. With ``whiten``: each chunk's output whitened as
        it comes (``noise.whiten`` into the group's arrays, while the chunk is in the cache), its finiteness
        looked at there, and None where a chunk is not finite (the caller then takes the path without,
        whose checks name the factor)."""
        ftype, keys, z, _ = self._groups[group]
        W = self._whitening[group] if whiten else None
        diagonal = self._diagonal[group] if whiten else None
        dims = [kind.dim for kind in ftype.kinds]
        held = self._held[group]
        jet = self.impl.module("jets").Jet
        tangent_jacobians = self.impl.module("autodiff_factor").tangent_jacobians
        where = "autodiff_factor.tangent_jacobians"
        m = ftype.dim
        r_all = np.empty((len(keys), m))
        J_all = [np.empty((len(keys), m, d)) for d in dims]
        rows = self._plus_rows[group]
        chunk = chunk_size(ftype)
        for start in range(0, len(keys), chunk):  # a chunk's Jets stay in the cache
            part = slice(start, start + chunk)
            count = len(keys[part])
            values = [x[part] for x in xs]
            # a slot held fixed in every factor of the chunk is a constant (no Jet directions): its block 0;
            # one held in some has its plus-Jacobian's rows 0 there: its block is 0, as the assembler takes it
            held_here = [None if h is None else h[part] for h in held]
            free = [a for a, h in enumerate(held_here) if h is None or not h.all()]
            plus = []
            for a, (h, row) in enumerate(zip(held_here, rows)):
                if a not in free:
                    J_all[a][part] = 0.0
                elif row is None:
                    P = ftype.kinds[a].plus_jacobian(values[a])
                    plus.append(P if h is None else np.where(h[:, None, None], 0.0, P))
                else:  # the kind's, found once per variable, gathered (a copy, zeroed in place where held)
                    P = np.take(self._plus_of_kind(x, ftype.kinds[a], plus_by_kind), row[part], axis=0)
                    if h is not None:
                        P[h] = 0.0
                    plus.append(P)

            def residual_of_part(*points, z_part=z[part], values=values, slots=free):
                full = list(values)
                for a, point in zip(slots, points):
                    full[a] = point
                return ftype.residual(z_part, *full)

            if not free:  # every variable fixed: the residual alone, its blocks 0
                r = self._checked(residual_of_part(), (count, m), "the residual", "r", group, start)
                noise.whiten(None if W is None else W[part], r, [], out=(r_all[part], []),
                             diagonal=None if diagonal is None else diagonal[part])
                continue
            r_part, J_part = None, {}
            for slots in ([[a] for a in free] if SLOT_BY_SLOT else [free]):
                r, J = tangent_jacobians(partial(residual_of_part, slots=slots), [plus[free.index(a)] for a in slots],
                                         [values[a] for a in slots], jet)
                if slots[0] == free[0]:
                    r_part = _shaped(r, (count, m), where, "r")
                if not isinstance(J, (list, tuple)) or len(J) != len(slots):
                    raise ShapeError(f"{where} returned {len(J) if isinstance(J, (list, tuple)) else type(J).__name__} "
                                     f"Jacobian blocks for the {len(slots)} plus-Jacobian(s) it was given "
                                     f"({ftype.name}, slot(s) {', '.join(map(str, slots))})")
                for i, (a, block) in enumerate(zip(slots, J)):
                    J_part[a] = _shaped(block, (count, m, dims[a]), where, f"J[{i}]")
            if whiten and not all(_sums_finite(out) for out in (r_part, *J_part.values())):
                return None
            noise.whiten(None if W is None else W[part], r_part, list(J_part.values()),
                         out=(r_all[part], [J_all[a][part] for a in J_part]),
                         diagonal=None if diagonal is None else diagonal[part])
        if whiten:
            return r_all, J_all
        # finite, each non-finite entry named by its factor in the group (one pass over each output)
        return self._checked(r_all, r_all.shape, where, "r", group, 0), [
            self._checked(block, block.shape, where, f"J[{a}]", group, 0) for a, block in enumerate(J_all)]

    def _plus_of_kind(self, x, kind, plus_by_kind: dict) -> np.ndarray:
        """``kind.plus_jacobian`` (N, size, dim) of all the ``N`` variables of ``kind`` at ``x``, found once
        into ``plus_by_kind``."""
        if kind not in plus_by_kind:
            members, x_index, _ = self._by_kind[kind]
            values = np.take(np.asarray(x), x_index).reshape((len(members),) + kind.shape)
            plus_by_kind[kind] = np.asarray(kind.plus_jacobian(values), dtype=float)
        return plus_by_kind[kind]

    @staticmethod
    def _held_still(held, J) -> list:
        """``J`` with the blocks of fixed variables 0 (``held``: per slot, (M,) or None), as the Jets give
        them: whichever path linearised, a fixed variable is not differentiated."""
        return [block if mask is None else np.where(mask[:, None, None], 0.0, block) for mask, block in zip(held, J)]

    def describe_factor(self, group: int, row: int) -> str:
        """``"factor 3000 of type 'between_se3' on 'x12', 'x13'"``: factor ``row`` of group ``group``."""
        ftype, keys, _, _ = self._groups[group]
        names = ", ".join(repr(self.graph.keys[v]) for v in keys[row])
        return f"factor {row} of type {ftype.name!r} on {names}"

    def _checked(self, value, shape, where: str, what: str, group: int, start: int) -> np.ndarray:
        """``check_array`` of a group's output (or of a chunk of it starting at factor ``start``), a
        non-finite entry named by its factor: its index in the group, its type and its variables' keys."""
        arr = np.asarray(value, dtype=float) if isinstance(value, np.ndarray) else value
        finite = None
        if isinstance(arr, np.ndarray) and arr.shape == tuple(shape):
            # a finite sum says every entry is finite (one pass, no mask); an infinite one (nan or inf
            # among them, or a sum that overflowed) is looked at entry by entry
            finite = bool(np.isfinite(arr.sum())) or bool(np.isfinite(arr).all())
            if finite:
                return arr
        if finite is False:
            index = tuple(int(k) for k in np.argwhere(~np.isfinite(arr))[0])
            row = start + index[0]
            raise NonFiniteError(
                f"{where} returned a non-finite {what} for {self.describe_factor(group, row)} "
                f"({self.graph.name}): {what}[{', '.join(map(str, (row,) + index[1:]))}] = {arr[index]}")
        return check_array(value, shape, where, what)

    def free_gauges(self) -> list:
        """The connected parts of the graph (by its factors) that hold no fixed variable (whole or partly)
        and no factor on one variable alone (a prior): ``[(number of variables, first key)]``. Their
        global pose is free."""
        parent = list(range(self.graph.num_variables))

        def root(v):
            while parent[v] != v:
                parent[v] = parent[parent[v]]
                v = parent[v]
            return v

        anchored = set(int(v) for v in self._fixed) | set(self.graph.fixed_dofs)  # partly fixed: said held
        for _, keys, _, _ in self._groups:
            if keys.shape[1] == 1:
                anchored.update(int(v) for v in keys[:, 0])
            for a in range(1, keys.shape[1]):
                for u, v in zip(keys[:, 0], keys[:, a]):
                    parent[root(int(u))] = root(int(v))
        held = {root(v) for v in anchored}
        parts: dict = {}
        for v in range(self.graph.num_variables):
            parts.setdefault(root(v), []).append(v)
        return [(len(members), self.graph.keys[members[0]]) for r, members in parts.items() if r not in held]

    def linearize(self, x) -> Linearization:
        blocks = []
        robust_correction = 0.0  # a robust group's chi2 is sum rho, not the reweighted residuals' sum r~^T r~
        plus_by_kind: dict = {}  # the variables' plus-Jacobians at x, found once for all the groups
        for group, (W, loss) in enumerate(zip(self._whitening, self._losses)):
            # the Jets' output whitened chunk by chunk; the other paths, or a non-finite output, whole
            whitened = self._autodiff(x, group, self._slots(x, group), plus_by_kind, whiten=True) \
                if self.jacobians == "autodiff" else None
            if whitened is None:
                r, J = self.factor_jacobians(x, group, plus_by_kind)
                whitened = noise.whiten(W, r, J, diagonal=self._diagonal[group])
            r, J = whitened
            # a held dof's Jacobian column zeroed (after the whitening, which mixes rows, not columns)
            J = [block if mask is None else block * mask[:, None, :]
                 for block, mask in zip(J, self._column_masks[group])]
            if loss is not None:  # r~, J~ with J~^T J~ = J^T W_rho J and J~^T r~ = rho' J^T r (chapter 4)
                r, J, rho = robust.reweight(self._kernels, loss, r, J)
                robust_correction += rho - float(np.vdot(r, r))
            blocks.append((r, list(J)))
        H, b, chi2 = self._assembler.assemble(blocks)
        chi2 = float(chi2) + robust_correction
        n = int(self._h_offsets[-1])
        b = check_array(b, (n,), "factor_linearisation.BlockSparseAssembler.assemble", "b")
        if not self._held_checked:  # the structure does not change between iterations: once is enough
            check_held_still(H, b, self._whole_fixed_dof, "factor_linearisation.BlockSparseAssembler.assemble",
                             int(max((k.dim for k in self.graph.kinds), default=1)))
            self._held_checked = True
        diagonal_positions = getattr(self._assembler, "diagonal_positions", None)
        if len(self._partial_dof):
            H, diagonal_positions = self._hold_partial(H, diagonal_positions)
        return Linearization(H=H, b=b, chi2=float(chi2), upper=True, diagonal_positions=diagonal_positions)

    def _hold_partial(self, H, diagonal_positions):
        """``H`` with 1 on the diagonal of the partly fixed variables' held dofs (their rows, columns and
        entries of b are zero: their Jacobian columns were), so that their step is 0: the framework's
        part, the assembly exercise's contract (whole variables) unchanged."""
        n = H.shape[0]
        if diagonal_positions is not None and sp.isspmatrix_csc(H) and len(diagonal_positions) == n:
            H.data[np.asarray(diagonal_positions)[self._partial_dof]] = 1.0
            return H, diagonal_positions
        one = np.ones(len(self._partial_dof))
        return sp.triu(H + sp.csc_matrix((one, (self._partial_dof, self._partial_dof)), shape=(n, n)),
                       format="csc"), None

    def solve(self, lin: Linearization, damping=None):
        """The step (n,) of ``(H + diag(damping)) h = -b``; fixed variables' steps, and the held dofs of
        partly fixed ones, are 0. A singular
        system says which parts of the graph have a free gauge (:meth:`free_gauges`), if any."""
        try:
            if self._schur is not None:
                h = self._schur.solve(lin.H, lin.b, damping)
                h[self._fixed_dof] = 0.0
                return h
            return checked_step(self._solver, lin.with_diagonal_added(damping), lin.b, self._fixed_dof,
                                self.graph.name, "variable")
        except SingularSystemError as exc:
            free = self.free_gauges()
            if not free or "gauge is free" in str(exc):
                raise
            parts = "; ".join(f"the {n} variable(s) joined to {key!r}" for n, key in free[:3])
            raise SingularSystemError(
                f"{exc}. The gauge is free: {parts} have no fixed variable and no prior, so their global "
                f"pose is not determined; fix one (graph.fix({free[0][1]!r})) or add a prior") from exc

    def retract(self, x, h):
        """Every variable moved by its step, kind by kind (vectorised)."""
        out = np.array(x, dtype=float)
        h = np.asarray(h, dtype=float)
        for kind, (members, x_index, h_index) in self._by_kind.items():
            moved = kind.retract(out[x_index].reshape((len(members),) + kind.shape), h[h_index])
            out[x_index] = np.asarray(moved, dtype=float).reshape(len(members), -1)
        return out


def _shaped(value, shape, where: str, what: str):
    """``value`` where it is an array of ``shape``, else ``check_array``'s error (its finiteness is checked
    once for the whole group, by ``FactorGraphProblem._checked``)."""
    if isinstance(value, np.ndarray) and value.shape == shape:
        return value
    return check_array(value, shape, where, what)


def _sums_finite(value: np.ndarray) -> bool:
    """Whether ``value`` is of floats and its sum finite: then every entry is (one pass, no mask); if not,
    an entry is not finite, or the sum overflowed, or the dtype is another."""
    return value.dtype == np.float64 and bool(np.isfinite(value.sum()))


def chunk_size(ftype) -> int:
    """The factors of type ``ftype`` per evaluation on Jets: ``CHUNK_BYTES`` over the bytes per factor of
    its widest seeded value (``n`` stored numbers, ``k`` directions: one slot's with ``SLOT_BY_SLOT``, all
    of them without), at least ``CHUNK_MIN``."""
    dims = [kind.dim for kind in ftype.kinds]
    k = max(dims) if SLOT_BY_SLOT else sum(dims)
    widest = max(int(np.prod(kind.shape)) for kind in ftype.kinds)
    return max(CHUNK_MIN, CHUNK_BYTES // (8 * widest * k))


def eliminated_kind(graph: FactorGraph):
    """The kind of variable to eliminate first, or None: of the kinds that no factor joins to another
    variable of their kind and that hold no fixed variable, while all other variables share one
    tangent size, the one with the most degrees of freedom, if it has at least as many as the rest."""
    kinds = graph.kinds
    fixed = set(graph.fixed)
    candidates = []
    for kind in dict.fromkeys(kinds):
        members = [v for v, k in enumerate(kinds) if k == kind]
        if any(v in fixed for v in members):
            continue
        if any(sum(k == kind for k in group.type.kinds) > 1 for group in graph.groups.values()):
            continue
        if len({k.dim for k in kinds if k != kind}) != 1:
            continue
        dof = kind.dim * len(members)
        rest = sum(k.dim for k in kinds) - dof
        if dof >= rest:
            candidates.append((dof, kind))
    return max(candidates, key=lambda c: c[0])[1] if candidates else None


def _column_masks(ftype, keys, fixed_dofs) -> list:
    """Per slot of a group, None or the mask (M, d_a) that zeroes the Jacobian columns of the dofs held
    of partly fixed variables (``FactorGraph.fix(key, dofs)``)."""
    masks = []
    for a, kind in enumerate(ftype.kinds):
        mask = None
        for v, dofs in fixed_dofs.items():
            rows = np.flatnonzero(keys[:, a] == v)
            if len(rows):
                mask = np.ones((len(keys), kind.dim)) if mask is None else mask
                mask[np.ix_(rows, list(dofs))] = 0.0
        masks.append(mask)
    return masks
