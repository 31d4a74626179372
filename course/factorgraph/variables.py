"""The kinds of variable a factor graph holds: how a value is stored and how a step moves it.

A kind has an ambient shape (how one value is stored, e.g. (12,) for an SE(3) pose: t then R row by
row), a tangent size ``dim`` (how many numbers a step has) and a retraction ``x (+) delta`` that maps
a step to a new value, vectorised over a batch: ``x`` (M, *shape), ``delta`` (M, dim). The
retractions run on arrays and on Jets (a Jet ``delta``), so that a factor's Jacobians with respect to
the tangent spaces are the derivatives of ``r(x (+) delta)`` at ``delta = 0``. Each kind also gives
the retraction's derivative there, ``plus_jacobian(x)`` = ``d vec(x (+) delta) / d delta`` at ``delta = 0``
(M, size, dim), in closed form (Ceres' ``Manifold::PlusJacobian``): by the chain rule the tangent
Jacobian is the stored coordinates' Jacobian times it, so that the Jets are seeded with it on the
stored values and no retraction runs on Jets (``autodiff_factor``). Each matches the chapter whose
problem it serves, so that the Jacobians compare with that chapter's:

- ``Vector(n)``: ``x + delta``; plus-Jacobian ``I``;
- ``SE2`` (x, y, theta): ``x + delta``, the angle wrapped (chapter 2: plain addition); ``I`` (the wrap
  subtracts a constant);
- ``SE3`` (t, R): ``(t + R rho, R Exp(phi))``, ``delta = (rho, phi)`` (chapter 6: on the right);
  ``d t / d rho = R``, ``d R / d phi_k = R [e_k]_x`` (``Exp(phi) = I + [phi]_x + O(|phi|^2)``), the
  other two blocks 0;
- ``SO3`` (R): ``R Exp(phi)``; ``d R / d phi_k = R [e_k]_x``;
- ``BAL_CAMERA`` (w, t, f, k1, k2): ``x + delta`` (chapter 4: plain addition, the angle-axis too); ``I``.
"""

from dataclasses import dataclass

import numpy as np

from course.factorgraph import jetmath


@dataclass(frozen=True)
class VariableKind:
    """A kind of variable: ``name``, ambient ``shape``, tangent ``dim``."""

    name: str
    shape: tuple
    dim: int

    def retract(self, x, delta):
        """``x (+) delta``: (M, *shape) from ``x`` (M, *shape) and ``delta`` (M, dim), arrays or Jets."""
        raise NotImplementedError

    def plus_jacobian(self, x) -> np.ndarray:
        """``d vec(x (+) delta) / d delta`` at ``delta = 0`` (M, size, dim) of values ``x`` (M, *shape)
        (``size = prod(shape)``, ``vec`` row by row as stored): what the Jets are seeded with."""
        raise NotImplementedError(f"the variable kind {self.name} gives retract but not plus_jacobian (the "
                                  "retraction's derivative at delta = 0, (M, size, dim)), which the automatic "
                                  "Jacobians seed the stored values with")

    def typed(self, value: np.ndarray):
        """One stored value (``shape``) as its users read it: an array here; an SE(3) pose a :class:`Pose3`."""
        return np.array(value, dtype=float).reshape(self.shape)

    def check(self, value, where: str) -> np.ndarray:
        """``value`` as a float array of this kind's shape, or a ``ValueError`` naming ``where``."""
        arr = np.asarray(value, dtype=float)
        if arr.shape != self.shape:
            raise ValueError(f"{where}: a value of kind {self.name} has shape {self.shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{where}: a value of kind {self.name} is not finite: {arr}")
        return arr


class Vector(VariableKind):
    def __init__(self, n: int):
        super().__init__(f"Vector{n}", (n,), n)

    def retract(self, x, delta):
        return x + delta

    def plus_jacobian(self, x) -> np.ndarray:
        return _identities(len(x), self.dim)


class SE2Kind(VariableKind):
    def __init__(self):
        super().__init__("SE2", (3,), 3)

    def retract(self, x, delta):
        moved = x + delta
        return np.stack([moved[..., 0], moved[..., 1], jetmath.wrap_angle(moved[..., 2])], axis=-1)

    def plus_jacobian(self, x) -> np.ndarray:
        return _identities(len(x), 3)


class SO3Kind(VariableKind):
    def __init__(self):
        super().__init__("SO3", (3, 3), 3)

    def retract(self, x, delta):
        return x @ jetmath.so3_exp(delta)

    def plus_jacobian(self, x) -> np.ndarray:
        return rotation_plus_jacobian(np.asarray(x, dtype=float))


@dataclass(frozen=True)
class Pose3:
    """An SE(3) pose: ``t`` (3,), ``R`` (3, 3); ``matrix()`` the 4x4 ``[[R, t], [0, 1]]``."""

    t: np.ndarray
    R: np.ndarray

    def matrix(self) -> np.ndarray:
        out = np.eye(4)
        out[:3, :3], out[:3, 3] = self.R, self.t
        return out


class SE3Kind(VariableKind):
    def __init__(self):
        super().__init__("SE3", (12,), 6)

    def typed(self, value: np.ndarray) -> Pose3:
        t, R = se3_parts(np.array(value, dtype=float))
        return Pose3(t, R)

    def retract(self, x, delta):
        t, R = se3_parts(x)
        t_new = t + jetmath.matvec(R, delta[..., :3])
        R_new = R @ jetmath.so3_exp(delta[..., 3:])
        return jetmath.concatenate([t_new, R_new.reshape(R_new.shape[:-2] + (9,))])

    def plus_jacobian(self, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return (x[:, 3:] @ _SE3_PLUS).reshape(len(x), 12, 6)


def rotation_plus_jacobian(R: np.ndarray) -> np.ndarray:
    """``d vec(R Exp(phi)) / d phi`` at ``phi = 0`` (M, 9, 3) of rotations ``R`` (M, 3, 3): column ``k`` is
    ``vec(R [e_k]_x)``, whose column ``j`` is ``R (e_k x e_j)``: ``R [e_0]_x = [0, R e_2, -R e_1]``,
    ``R [e_1]_x = [-R e_2, 0, R e_0]``, ``R [e_2]_x = [R e_1, -R e_0, 0]``. Linear in ``R``: one product of
    the rows of ``R`` with the constant ``[e_k]_x`` (each entry one term, exact)."""
    R = np.asarray(R, dtype=float)
    return (R.reshape(-1, 3) @ _GENERATORS).reshape(len(R), 9, 3)


def _generators() -> np.ndarray:
    """``G`` (3, 9) with ``G[l, 3 j + k] = [e_k]_x[l, j]``: row ``i`` of ``R`` times it is row ``i`` of every
    ``R [e_k]_x``, as ``rotation_plus_jacobian`` lays them out."""
    G = np.zeros((3, 3, 3))
    for k in range(3):
        e = np.zeros(3)
        e[k] = 1.0
        G[:, :, k] = np.cross(e, np.eye(3)).T  # column j of [e_k]_x is e_k x e_j
    return G.reshape(3, 9)


def _se3_plus() -> np.ndarray:
    """``L`` (9, 72): the stored R's row by row (9,) times it is the SE(3) plus-Jacobian (12, 6), flattened:
    ``d t / d rho = R`` and ``d vec(R) / d phi`` from :data:`_GENERATORS` (each entry one term, exact)."""
    L = np.zeros((3, 3, 12, 6))  # [i, j, row, column]: the coefficient of R[i, j]
    for i in range(3):
        for j in range(3):
            L[i, j, i, j] = 1.0
            L[i, j, 3 + 3 * i:6 + 3 * i, 3:] = _GENERATORS[j].reshape(3, 3)
    return L.reshape(9, 72)


_GENERATORS = _generators()
_SE3_PLUS = _se3_plus()


def _identities(M: int, n: int) -> np.ndarray:
    """``I`` (M, n, n): the plus-Jacobian of plain addition."""
    return np.broadcast_to(np.eye(n), (M, n, n)).copy()


def se3_parts(x):
    """``(t (..., 3), R (..., 3, 3))`` of SE(3) values (..., 12)."""
    return x[..., :3], x[..., 3:].reshape(x.shape[:-1] + (3, 3))


def se3_value(t, R) -> np.ndarray:
    """The stored value (12,) or (M, 12) of a pose ``(t, R)``."""
    t, R = np.asarray(t, dtype=float), np.asarray(R, dtype=float)
    return np.concatenate([t, R.reshape(R.shape[:-2] + (9,))], axis=-1)


class BALCameraKind(Vector):
    """A BAL camera ``(w, t, f, k1, k2)`` (9,), updated by plain addition as in chapter 4."""

    def __init__(self):
        VariableKind.__init__(self, "BALCamera", (9,), 9)


SE2 = SE2Kind()
BAL_CAMERA = BALCameraKind()
SO3 = SO3Kind()
SE3 = SE3Kind()
