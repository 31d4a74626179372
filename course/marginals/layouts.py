"""Each problem family's variables, as the marginals see them: keys, tangent sizes, held dofs, gauge.

A :class:`Layout` names the variables of a problem's step ``h`` (n,) in its order: ``keys`` (m,),
``sizes`` (m,) their tangent sizes (``sum(sizes) = n``), ``held`` (n,) bool the dofs the problem holds
still (a fixed pose: its rows and columns of H are the identity's, its covariance is 0), and ``gauge``,
what is free when nothing holds the problem in place (said when H is singular).

A pose graph with no fixed pose, bundle adjustment without its gauge fixed, a factor graph with a free
part and a VIO problem without an anchor or a prior are refused (:class:`GaugeError`, naming the gauge):
rounding leaves a singular H with small positive pivots, which a factorisation need not notice.

The covariances are in each family's tangent, the coordinates of its step ``h``:

- curve fit: one variable, key ``"params"``, the parameters (3,) as they are (``p + h``);
- 2D pose graph: key ``k`` (pose index), ``(dx, dy, dtheta)`` in the world frame (``x + h``);
- 3D pose graph: key ``k``, ``(rho, phi)``, translation first, on the right (``t + R rho, R Exp(phi)``);
- bundle adjustment: keys ``("camera", c)`` (the 9 BAL parameters ``w, t, f, k1, k2``, added) and
  ``("point", p)`` (3, added). Its H is singular along the 7-dimensional gauge (a similarity of the
  whole scene): a problem made with ``fix_gauge=True`` (chapter 4's gauge: camera 0's pose and one
  translation component of camera 1 held) has marginals, with those held dofs 0; without it,
  :func:`layout_of` refuses, naming the gauge;
- chapter 7's factor graph: the graph's keys, each kind's tangent (``course.factorgraph.variables``);
  fixed variables and fixed dofs held; a part of the graph with a free gauge (``free_gauges``) refused;
- VIO window: keys ``("frame", f)`` (15: ``dphi, dp, dv, db_g, db_a``) and ``("landmark", l)`` (3).
"""

from dataclasses import dataclass

import numpy as np

from course.core.errors import SingularSystemError

#: the problem classes by their module: each family is imported only for its own problems (a student tree
#: of an early assignment holds the early chapters' families alone)
FAMILIES = {
    "course.problems.curve.problem": "CurveProblem",
    "course.problems.posegraph.problem": "PoseGraphProblem",
    "course.problems.posegraph3d.problem": "PoseGraph3DProblem",
    "course.problems.bal.problem": "BundleAdjustmentProblem",
    "course.factorgraph.problem": "FactorGraphProblem",
    "course.problems.vio.problem": "VioProblem",
}


class GaugeError(SingularSystemError):
    """The problem's H is singular along a gauge freedom that nothing holds: no marginals."""


@dataclass(frozen=True)
class Layout:
    """``keys`` (m,), ``sizes`` (m,) tangent sizes, ``held`` (n,) bool, ``gauge`` (see the module docstring)."""

    keys: list
    sizes: np.ndarray
    held: np.ndarray
    gauge: str = ""

    @property
    def starts(self) -> np.ndarray:
        return np.concatenate([[0], np.cumsum(self.sizes)]).astype(np.int64)


def _held_poses(num, dof, fixed) -> np.ndarray:
    held = np.zeros(num * dof, dtype=bool)
    held[(dof * np.asarray(fixed, dtype=np.int64)[:, None] + np.arange(dof)).ravel()] = True
    return held


def layout_of(problem) -> Layout:
    """The :class:`Layout` of a problem of one of the course's families (the module docstring); a
    ``TypeError`` for anything else, :class:`GaugeError` for bundle adjustment without its gauge fixed and
    a factor graph with a free part."""
    kind = next((name for module, name in FAMILIES.items()
                 for cls in type(problem).__mro__ if cls.__module__ == module and cls.__name__ == name), None)
    if kind == "CurveProblem":
        n = len(problem.x0)
        return Layout(["params"], np.array([n]), np.zeros(n, dtype=bool))
    if kind == "PoseGraphProblem":
        g = problem.graph
        if not len(g.fixed):
            raise GaugeError(f"{g.name}: H is singular along the gauge: no pose is fixed, so the whole graph can "
                             "move (3 gauge freedoms: x, y, theta); fix one pose (graph.fixed)")
        return Layout(list(range(g.num_poses)), np.full(g.num_poses, 3), _held_poses(g.num_poses, 3, g.fixed),
                      f"{g.name}: no pose is fixed, so the whole graph can move (3 gauge freedoms: x, y, theta); "
                      "fix one pose")
    if kind == "PoseGraph3DProblem":
        g3 = problem.graph
        if not len(g3.fixed):
            raise GaugeError(f"{g3.name}: H is singular along the gauge: no pose is fixed, so the whole graph can "
                             "move (6 gauge freedoms); fix one pose (graph.fixed)")
        return Layout(list(range(g3.num_poses)), np.full(g3.num_poses, 6), _held_poses(g3.num_poses, 6, g3.fixed),
                      f"{g3.name}: no pose is fixed, so the whole graph can move (6 gauge freedoms); fix one pose")
    if kind == "BundleAdjustmentProblem":
        if not problem.fixed.any():
            raise GaugeError("bundle adjustment's H is singular along its 7-dimensional gauge (a rotation, a "
                             "translation and a scale of the whole scene): make the problem with fix_gauge=True "
                             "(camera 0's pose and one translation component of camera 1 held, chapter 4's gauge) "
                             "for its marginals")
        C, P = problem.num_cameras, problem.num_points
        keys = [("camera", c) for c in range(C)] + [("point", p) for p in range(P)]
        held = np.concatenate([problem.fixed.ravel(), np.zeros(3 * P, dtype=bool)])
        return Layout(keys, np.array([9] * C + [3] * P), held,
                      "bundle adjustment: the held parameters do not fix the 7-dimensional gauge")
    if kind == "FactorGraphProblem":
        return _factor_graph(problem)
    if kind == "VioProblem":
        from course.problems.vio.problem import FRAME_DOF, POINT_DOF

        d = problem.data
        if d.anchor is None and d.linear_prior is None and not d.frame_priors:
            raise GaugeError("vio: H is singular along the gauge: a visual-inertial problem without an anchor or a "
                             "prior has 4 gauge freedoms (the yaw and the position); give VioData an anchor or a "
                             "frame prior")
        F, L = problem.num_frames, problem.num_landmarks
        keys = [("frame", f) for f in range(F)] + [("landmark", k) for k in range(L)]
        return Layout(keys, np.array([FRAME_DOF] * F + [POINT_DOF] * L), np.zeros(problem.n, dtype=bool),
                      "vio: a visual-inertial problem without an anchor or a prior has 4 gauge freedoms (the "
                      "yaw and the position); give VioData an anchor or a frame prior")
    raise TypeError(f"marginals: {type(problem).__name__} is not a problem of the course's families (curve, pose "
                    "graph 2D or 3D, bundle adjustment, factor graph, VIO); pass its H with Marginals.of_information")


def _factor_graph(problem) -> Layout:
    """A ``FactorGraphProblem``'s layout."""
    g = problem.graph
    free = problem.free_gauges()
    if free:
        parts = "; ".join(f"{size} variables from {key!r}" for size, key in free)
        raise GaugeError(f"{g.name}: H is singular along the gauge of the parts of the graph that nothing "
                         f"holds ({parts}): fix a variable of each (graph.fix) or add a prior")
    sizes = np.array([k.dim for k in g.kinds], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    held = np.zeros(int(starts[-1]), dtype=bool)
    for v in g.fixed:
        held[starts[v]:starts[v + 1]] = True
    for v, dofs in g.fixed_dofs.items():
        held[starts[v] + np.asarray(dofs, dtype=np.int64)] = True
    return Layout(list(g.keys), sizes, held, f"{g.name}: H is singular (a gauge or a variable that no factor "
                                             "determines)")
