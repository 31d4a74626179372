"""A Jacobian checker for your own derivations: ``check_jacobian(f, x, J, plus=...)``.

It moves each variable along every direction of its tangent space through the retraction the
chapters use (``x (+) delta``), takes central differences of ``f`` and compares them with the
Jacobian you derived, entry by entry. It prints the worst entries and the block each sits in
(which variable, which rows and columns: translation or rotation) and returns a
:class:`JacobianCheck`.

The spaces (``plus=``), and the order of each one's tangent coordinates:

- ``"vector"``: any array; ``x + delta`` (its entries in C order).
- ``"se2"``: a pose ``(x, y, theta)`` (or (N, 3) poses) as chapter 2 moves them:
  ``(x, y, theta) + delta``, the angle wrapped; tangent ``(x, y, theta)`` per pose.
- ``"so3"``: a rotation matrix (3, 3) (or (N, 3, 3)) moved on the right: ``R Exp(phi)``.
- ``"se3"``: a pose ``(t, R)`` (t (3,) or (N, 3), R (3, 3) or (N, 3, 3)) moved on the right as
  chapter 6 does: ``(t + R rho, R Exp(phi))``; tangent ``(rho, phi)`` per pose, translation first.

Several variables: pass a list ``x = [x_1, x_2]`` (``f(x_1, x_2)``), with ``J = [J_1, J_2]``
and ``plus`` one name or one per variable. A Jacobian is ``(rows, tangent size)``, or, for N
poses each with its own output block (a vectorized edge: ``A`` (M, 6, 6)), the (M, r, c) stack
of the diagonal blocks. ``rows="se3"`` (or ``"se2"``) names the output's rows translation and
rotation (per edge when the output is (M, 6)).

    >>> from course.geometry.jacobian_check import check_jacobian
    >>> result = check_jacobian(lambda T_i, T_j: my_error(T_i, T_j), [T_i, T_j], J=[A, B],
    ...                         plus="se3", names=["T_i", "T_j"], rows="se3")
    >>> result.ok
    True

Without ``J`` it only prints and returns the numerical Jacobian (``result.numeric``).
"""

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from course.geometry.se2 import wrap_angle
from course.geometry.so3 import exp_many

#: the relative step of the central differences (times max(1, |x|) for vector spaces)
STEP = 1e-6


@dataclass(frozen=True)
class Space:
    """A space to move a variable in: ``plus(x, delta)`` with ``delta`` the flat tangent vector of
    ``dim(x)`` entries, and ``parts``, the names of the blocks of one element's tangent
    coordinates (``("translation", slice(0, 3))``)."""

    name: str
    dim: Callable
    plus: Callable
    element: int  # tangent size of one element (a pose, a rotation); 1 for a vector space
    parts: tuple = ()


def _vector_plus(x, delta):
    x = np.asarray(x, dtype=float)
    return x + np.asarray(delta, dtype=float).reshape(x.shape)


def _se2_plus(x, delta):
    poses = np.asarray(x, dtype=float)
    moved = poses + np.asarray(delta, dtype=float).reshape(poses.shape)
    moved[..., 2] = wrap_angle(moved[..., 2])
    return moved


def _so3_plus(R, delta):
    R = np.asarray(R, dtype=float)
    return (R.reshape(-1, 3, 3) @ exp_many(np.asarray(delta, dtype=float).reshape(-1, 3))).reshape(R.shape)


def _se3_parts(x):
    if isinstance(x, np.ndarray) and x.shape[-2:] == (4, 4):
        return x[..., :3, 3], x[..., :3, :3], True
    t, R = x
    return np.asarray(t, dtype=float), np.asarray(R, dtype=float), False


def _se3_plus(x, delta):
    t, R, matrix = _se3_parts(x)
    d = np.asarray(delta, dtype=float).reshape(-1, 6)
    Rs = R.reshape(-1, 3, 3)
    t_new = (t.reshape(-1, 3) + np.einsum("nab,nb->na", Rs, d[:, :3])).reshape(t.shape)
    R_new = (Rs @ exp_many(d[:, 3:])).reshape(R.shape)
    if matrix:
        out = np.array(x, dtype=float)
        out[..., :3, :3], out[..., :3, 3] = R_new, t_new
        return out
    return t_new, R_new


TRANSLATION_ROTATION = (("translation", slice(0, 3)), ("rotation", slice(3, 6)))

#: the spaces ``plus=`` names
SPACES = {
    "vector": Space("vector", lambda x: np.asarray(x).size, _vector_plus, 1),
    "se2": Space("se2", lambda x: np.asarray(x).size, _se2_plus, 3,
                 (("translation", slice(0, 2)), ("rotation", slice(2, 3)))),
    "so3": Space("so3", lambda R: np.asarray(R).size // 3, _so3_plus, 3, (("rotation", slice(0, 3)),)),
    "se3": Space("se3", lambda x: 6 * (_se3_parts(x)[0].size // 3), _se3_plus, 6, TRANSLATION_ROTATION),
}


def space(plus) -> Space:
    """The :class:`Space` ``plus`` names (or ``plus`` itself)."""
    if isinstance(plus, Space):
        return plus
    name = "vector" if plus is None else str(plus).lower().replace("(", "").replace(")", "")
    if name not in SPACES:
        raise ValueError(f"plus={plus!r}: choose from {', '.join(SPACES)} or give a Space")
    return SPACES[name]


@dataclass
class Entry:
    """One entry of the Jacobian: its row and column in the whole matrix, where it sits, and both values."""

    row: int
    column: int
    analytic: float
    numeric: float
    variable: str
    column_block: str  # "rotation (column 1 of 3)", "pose 2 translation (column 0 of 3)"
    row_block: str  # "rotation", "edge 0 translation", "row 4"

    @property
    def error(self) -> float:
        return abs(self.analytic - self.numeric)

    @property
    def block(self) -> str:
        """``"d rotation / d T_i rotation"``: the block of the Jacobian the entry sits in."""
        rows = self.row_block.split(" (")[0]
        return f"d {rows} / d {self.variable} {self.column_block.split(' (')[0]}".replace("  ", " ").strip()


@dataclass
class JacobianCheck:
    """What :func:`check_jacobian` found. ``ok``: every entry within the tolerance (True when no
    ``J`` was given); ``numeric`` and ``analytic`` the whole (rows, columns) matrices (``analytic``
    None without ``J``); ``worst`` the entries off by more than the tolerance, worst first (at most
    ``show``); ``blocks`` ``{block: largest error}`` of the blocks holding a wrong entry;
    ``max_error`` the largest ``|analytic - numeric|``; ``tolerance`` what an entry may differ by."""

    ok: bool
    numeric: np.ndarray
    analytic: np.ndarray | None
    max_error: float
    tolerance: float
    worst: list = field(default_factory=list)
    blocks: dict = field(default_factory=dict)
    wrong: int = 0

    def report(self) -> str:
        """The text :func:`check_jacobian` prints."""
        shape = f"{self.numeric.shape[0]} x {self.numeric.shape[1]}"
        if self.analytic is None:
            return f"numerical Jacobian ({shape}, central differences):\n{np.array2string(self.numeric, precision=6)}"
        if self.ok:
            return (f"Jacobian OK: {shape}, every entry within {self.tolerance:.1e} of central differences "
                    f"(largest difference {self.max_error:.1e})")
        lines = [f"Jacobian WRONG: {self.wrong} of {self.numeric.size} entries differ from central differences "
                 f"by more than {self.tolerance:.1e} (largest {self.max_error:.3g})",
                 "blocks with a wrong entry (largest difference):"]
        lines += [f"  {block}: {error:.3g}" for block, error in self.blocks.items()]
        lines.append("worst entries:")
        for e in self.worst:
            lines.append(f"  J[{e.row}, {e.column}]  yours {e.analytic: .6g}  numeric {e.numeric: .6g}  "
                         f"(row {e.row_block}; column {e.variable} {e.column_block})")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.report()


def _as_list(value, count, what):
    if isinstance(value, list):
        if len(value) != count:
            raise ValueError(f"{what}: {len(value)} given for {count} variable(s)")
        return value
    return [value] * count


def _column_names(var_space: Space, dim: int) -> list:
    """Per tangent coordinate of one variable: its block and place (``"pose 1 rotation (column 2 of 3)"``)."""
    k = var_space.element
    count = dim // k if k else dim
    names = []
    for index in range(dim):
        element, local = divmod(index, k)
        prefix = f"pose {element} " if count > 1 and var_space.parts else ""
        if not var_space.parts:
            names.append(f"(entry {index})")
            continue
        for part, where in var_space.parts:
            if where.start <= local < where.stop:
                size = where.stop - where.start
                names.append(f"{prefix}{part} (column {local - where.start} of {size})")
    return names


def _row_names(rows, m: int) -> list:
    if rows is None:
        return [f"row {r}" for r in range(m)]
    if isinstance(rows, str):
        parts = space(rows).parts
        k = max(s.stop for _, s in parts)
        if m % k:
            raise ValueError(f"rows={rows!r}: {m} rows are not a whole number of {k}-row blocks")
        names = []
        for r in range(m):
            element, local = divmod(r, k)
            part = next(name for name, s in parts if s.start <= local < s.stop)
            names.append(f"{'edge ' + str(element) + ' ' if m > k else ''}{part}")
        return names
    names = [f"row {r}" for r in range(m)]
    for name, where in rows:
        for r in range(m)[where]:
            names[r] = name
    return names


def _dense(J, m: int, n: int, what: str) -> np.ndarray:
    """``J`` as an (m, n) matrix; an (N, r, c) stack with N r = m and N c = n is block-diagonal."""
    J = np.asarray(J, dtype=float)
    if J.ndim == 3 and J.shape[0] * J.shape[1] == m and J.shape[0] * J.shape[2] == n:
        out = np.zeros((m, n))
        N, r, c = J.shape
        for k in range(N):
            out[k * r:(k + 1) * r, k * c:(k + 1) * c] = J[k]
        return out
    if J.size != m * n:
        raise ValueError(f"{what} has shape {J.shape}; expected ({m}, {n}) (outputs x tangent size), "
                         "or a stack of per-element blocks")
    return J.reshape(m, n)


def numerical_jacobian(f, x, plus=None, step=STEP) -> np.ndarray:
    """Central differences of ``f`` through ``plus`` at ``x`` (lists as in :func:`check_jacobian`):
    the (outputs, total tangent size) matrix."""
    xs = x if isinstance(x, list) else [x]
    spaces = [space(p) for p in _as_list(plus, len(xs), "plus")]
    columns = []
    for k, (value, where) in enumerate(zip(xs, spaces)):
        h = step * (max(1.0, float(np.max(np.abs(value)))) if where.name == "vector" else 1.0)
        dim = where.dim(value)
        for c in range(dim):
            delta = np.zeros(dim)
            delta[c] = h
            args_plus, args_minus = list(xs), list(xs)
            args_plus[k], args_minus[k] = where.plus(value, delta), where.plus(value, -delta)
            up = np.asarray(f(*args_plus), dtype=float).ravel()
            down = np.asarray(f(*args_minus), dtype=float).ravel()
            columns.append((up - down) / (2.0 * h))
    return np.stack(columns, axis=1)


def check_jacobian(f: Callable, x, J=None, plus=None, names: Sequence[str] | None = None, rows=None,
                   step: float = STEP, tolerance: float = 1e-5, show: int = 5, out=print) -> JacobianCheck:
    """Compare the Jacobian ``J`` of ``f`` at ``x`` with central differences through ``plus``.

    Args:
        f: the function, ``f(x)`` or ``f(x_1, x_2, ...)``, returning an array (flattened: the rows).
        x: a variable, or a list of variables (see the module docstring for each space's form).
        J: your Jacobian (or a list, one per variable), ``(rows, tangent size)`` or a stack of
            per-element blocks; None: only compute the numerical one.
        plus: ``"vector"`` (default), ``"se2"``, ``"so3"``, ``"se3"`` or a :class:`Space`; one, or
            a list with one per variable.
        names: the variables' names in the report (default ``x``, or ``x1``, ``x2``, ...).
        rows: how to name the output's rows: ``"se3"``/``"se2"`` (translation, rotation), a list
            of ``(name, slice)``, or None (``row k``).
        step: the central differences' step (tangent units).
        tolerance: an entry is wrong when ``|yours - numeric| > tolerance * max(1, max |numeric|)``.
        show: how many of the worst entries to print.
        out: where the report goes (``print``; None: nowhere).

    Returns:
        a :class:`JacobianCheck` (``.ok``, ``.worst``, ``.blocks``, ``.numeric``, ``.report()``).
    """
    xs = x if isinstance(x, list) else [x]
    spaces = [space(p) for p in _as_list(plus, len(xs), "plus")]
    if names is None:
        names = ["x"] if len(xs) == 1 else [f"x{k + 1}" for k in range(len(xs))]
    if len(names) != len(xs):
        raise ValueError(f"names: {len(names)} given for {len(xs)} variable(s)")
    numeric = numerical_jacobian(f, xs, spaces, step)
    m = numeric.shape[0]
    dims = [s.dim(v) for s, v in zip(spaces, xs)]
    if J is None:
        result = JacobianCheck(True, numeric, None, 0.0, tolerance)
    else:
        Js = J if isinstance(J, list) else [J]
        if len(Js) != len(xs):
            raise ValueError(f"J: {len(Js)} Jacobian(s) given for {len(xs)} variable(s)")
        analytic = np.concatenate([_dense(Jk, m, d, f"J of {name}") for Jk, d, name in zip(Js, dims, names)], axis=1)
        tol = tolerance * max(1.0, float(np.max(np.abs(numeric))))
        diff = np.abs(analytic - numeric)
        diff[~np.isfinite(diff)] = np.inf
        row_names = _row_names(rows, m)
        col_info = [(name, col) for name, s, d in zip(names, spaces, dims) for col in _column_names(s, d)]
        bad = np.argwhere(diff > tol)
        order = sorted(map(tuple, bad), key=lambda rc: -diff[rc])
        entries = [Entry(int(r), int(c), float(analytic[r, c]), float(numeric[r, c]), col_info[c][0], col_info[c][1],
                         row_names[r]) for r, c in order]
        blocks: dict = {}
        for e in entries:
            blocks[e.block] = max(blocks.get(e.block, 0.0), e.error)
        result = JacobianCheck(not entries, numeric, analytic, float(np.max(diff)) if diff.size else 0.0, tol,
                               entries[:show], blocks, len(entries))
    if out is not None:
        out(result.report())
    return result
