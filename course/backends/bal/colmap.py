"""Bundle adjustment through COLMAP's Ceres back end: ``pycolmap.bundle_adjustment`` (C++ cost).

Cost convention: Ceres' ``0.5 * sum |r|^2`` (trivial loss, unit weights, residuals in
pixels): the BAL cost, but only over the observations COLMAP keeps. Observations behind
the camera: before it solves, ``pycolmap.bundle_adjustment`` (COLMAP's bundle-adjustment
controller) deletes every observation whose point has no positive depth in its camera,
and a point left with fewer than two observations goes with them. On ladybug-49 all
the observations of 10 points are behind their cameras: 10 points and 31 observations
go (``removed_points``, ``removed_observations``), and Ceres' initial cost is 850802.09
where ours, over all 31843 observations, is 850912.46. A removed point keeps its start
value in ``params``, and its observations count in our ``final_chi2``. During the solve
COLMAP's reprojection cost scores an observation whose point crosses behind the camera
zero (COLMAP's source: a failed projection sets the residual and its Jacobian to zero);
ours does not (on ladybug-49, 50 dogleg iterations leave 43 observations behind their
cameras: Ceres' cost 16492.08, ours 1.5e54).

Conversion (BAL looks down -z, COLMAP down +z): with ``F = diag(1, -1, -1)`` (pi about
x), ``cam_from_world = (F R(w), F t)`` and the observation ``(u, -v)``; camera model
``RADIAL`` with ``params = [f, cx=0, cy=0, k1, k2]`` (the BAL distortion
``1 + k1 |p|^2 + k2 |p|^4``), ``refine_principal_point = False``. One camera, trivial rig
and frame per BAL camera; one 3D point per BAL point, its track the BAL observations.
Back: ``R = F R'``, ``t = F t'``, ``w`` its angle-axis vector, ``f, k1, k2`` from the
params. COLMAP fixes the gauge itself (the first image's pose and one translation
coordinate of a second: ``TWO_CAMS_FROM_WORLD``) and picks the linear solver from the
number of images (``DENSE_SCHUR`` up to 50, ``SPARSE_SCHUR`` up to 1000, else
``ITERATIVE_SCHUR``); the controller's own tolerances (gradient 1e-4) are replaced here.

The trace: pycolmap 4.2.1 exposes no iteration callback, and ``bundle_adjustment``
returns nothing. So ``solve`` turns on Ceres' per-iteration table
(``minimizer_progress_to_stdout``, ``LoggingType.PER_MINIMIZER_ITERATION``), which Ceres
prints on the C-level standard output, and COLMAP's report (glog, standard error);
it redirects both file descriptors to temporary files during the call and parses them.
Unless ``pycolmap.logging.log_dir`` is set, it also turns off glog's log files for the
process (by default pycolmap leaves one per process in the temporary folder).
The table gives, per iteration, Ceres' cost (7 significant digits), its trust-region
ratio and radius, and the time (3 significant digits). Where the table cannot be
captured (no C stdio to flush, e.g. on some Windows builds), the trace is empty and
``stop_reason`` says so; ``final_chi2`` is still ours at the solution.
"""

from __future__ import annotations

import ctypes
import math
import os
import re
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np

from course.backends import registry
from course.backends.bal.common import (
    FLIP,
    BALRunResult,
    angle_axis,
    check_max_iterations,
    check_method,
    pack,
    rotation_matrices,
)
from course.core import peers
from course.core.trace import IterationRecord
from course.problems.bal.dataset import BALProblem, behind_camera, cost

METHODS = registry.peer_methods("bal", "ceres")
PEER_COST = "Ceres' 0.5 sum |r|^2 over the observations COLMAP keeps (points behind a camera deleted)"

#: one line of Ceres' per-iteration table: iter cost cost_change |gradient| |step| tr_ratio
#: tr_radius ls_iter iter_time total_time
_ROW = re.compile(r"^\s*(\d+)" + r"\s+([-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|nan|inf))" * 9 + r"\s*$")


@contextmanager
def captured_output() -> Iterator[dict]:
    """Redirect the process's file descriptors 1 and 2 (what C++ and glog write to) to
    temporary files; yields a dict that holds ``"stdout"`` and ``"stderr"`` text afterwards."""
    texts: dict = {}
    sys.stdout.flush()
    sys.stderr.flush()
    saved, files = {}, {}
    try:
        for fd in (1, 2):
            files[fd] = tempfile.TemporaryFile()
            saved[fd] = os.dup(fd)
            os.dup2(files[fd].fileno(), fd)
        yield texts
    finally:
        _flush_c_stdio()
        for fd, name in ((1, "stdout"), (2, "stderr")):
            if fd in saved:
                os.dup2(saved[fd], fd)
                os.close(saved[fd])
            if fd in files:
                files[fd].seek(0)
                texts[name] = files[fd].read().decode("utf-8", errors="replace")
                files[fd].close()


def _flush_c_stdio() -> None:
    """``fflush(NULL)``: Ceres' table sits in C's stdout buffer when stdout is a file."""
    try:
        libc = ctypes.CDLL(None) if os.name != "nt" else ctypes.cdll.msvcrt
        libc.fflush(None)
    except (OSError, AttributeError):  # no C library to reach: the table may be lost (see the module doc)
        pass


def parse_iterations(text: str) -> list[dict]:
    """The rows of Ceres' per-iteration table in ``text``: dicts with ``iteration``, ``cost``,
    ``cost_change``, ``gradient``, ``step``, ``tr_ratio``, ``tr_radius``, ``iter_time``, ``total_time``."""
    rows = []
    for line in text.splitlines():
        match = _ROW.match(line)
        if match:
            values = [float(v) for v in match.groups()[1:]]
            rows.append(dict(iteration=int(match.group(1)), cost=values[0], cost_change=values[1],
                             gradient=values[2], step=values[3], tr_ratio=values[4], tr_radius=values[5],
                             iter_time=values[7], total_time=values[8]))
    return rows


def parse_report(text: str) -> dict:
    """COLMAP's bundle-adjustment report (glog): ``termination``, ``iterations``, ``time`` when found."""
    out: dict = {}
    for key, pattern, kind in (("termination", r"Termination\s*:\s*(\w+)", str),
                               ("iterations", r"Iterations\s*:\s*(\d+)", int),
                               ("time", r"Time\s*:\s*([0-9.eE+-]+)\s*\[s\]", float)):
        match = re.search(pattern, text)
        if match:
            out[key] = kind(match.group(1))
    return out


def to_reconstruction(problem: BALProblem):
    """``(reconstruction, point_ids)``: ``problem`` as a ``pycolmap.Reconstruction`` (see the module
    docstring); camera and image c have id c + 1, ``point_ids[j]`` is BAL point j's 3D point id."""
    import pycolmap

    C = problem.num_cameras
    R = rotation_matrices(problem.cameras[:, :3])
    reconstruction = pycolmap.Reconstruction()
    slot = np.zeros(problem.num_observations, dtype=np.int64)  # each observation's keypoint index in its image
    for c in range(C):
        mine = np.flatnonzero(problem.camera_index == c)
        slot[mine] = np.arange(len(mine))
        uv = problem.observations[mine] * np.array([1.0, -1.0])
        size = max(2, 2 * math.ceil(float(np.max(np.abs(uv), initial=1.0))))  # not used by bundle adjustment
        f, k1, k2 = problem.cameras[c, 6:9].tolist()
        camera = pycolmap.Camera(model="RADIAL", width=size, height=size, params=[f, 0.0, 0.0, k1, k2],
                                 camera_id=c + 1)
        reconstruction.add_camera_with_trivial_rig(camera)
        image = pycolmap.Image(name=f"camera_{c}", keypoints=np.ascontiguousarray(uv), camera_id=c + 1,
                               image_id=c + 1)
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(FLIP @ R[c]), FLIP @ problem.cameras[c, 3:6])
        reconstruction.add_image_with_trivial_frame(image, pose)
    tracks = [pycolmap.Track() for _ in range(problem.num_points)]
    for c, j, k in zip(problem.camera_index.tolist(), problem.point_index.tolist(), slot.tolist()):
        tracks[j].add_element(c + 1, k)
    point_ids = np.array([reconstruction.add_point3D(problem.points[j], tracks[j])
                          for j in range(problem.num_points)], dtype=np.int64)
    return reconstruction, point_ids


def from_reconstruction(problem: BALProblem, reconstruction, point_ids):
    """``(cameras (C, 9), points (P, 3), kept (P,) bool)``: the BAL state of ``reconstruction``;
    a point COLMAP deleted keeps its value in ``problem.points`` (``kept`` False)."""
    C = problem.num_cameras
    R, t = np.empty((C, 3, 3)), np.empty((C, 3))
    cameras = problem.cameras.copy()
    for c in range(C):
        pose = reconstruction.images[c + 1].cam_from_world()
        R[c] = FLIP @ pose.rotation.matrix()
        t[c] = FLIP @ np.asarray(pose.translation)
        params = np.asarray(reconstruction.cameras[c + 1].params)
        cameras[c, 6:9] = params[[0, 3, 4]]
    cameras[:, :3] = angle_axis(R, near=problem.cameras[:, :3])
    cameras[:, 3:6] = t
    points = problem.points.copy()
    kept = np.array([reconstruction.exists_point3D(int(i)) for i in point_ids], dtype=bool)
    for j in np.flatnonzero(kept).tolist():
        points[j] = reconstruction.points3D[int(point_ids[j])].xyz
    return cameras, points, kept


def solve(
    problem: BALProblem,
    method: str = "levenberg-marquardt",
    max_iterations: int = 100,
    *,
    function_tolerance: float = 1e-12,
    parameter_tolerance: float = 1e-12,
    gradient_tolerance: float = 1e-14,
    num_threads: int = 1,
    verbose: bool = False,
) -> BALRunResult:
    """Bundle-adjust ``problem`` from its own start with ``pycolmap.bundle_adjustment``.

    ``method``: ``levenberg-marquardt`` or ``dogleg`` (Ceres' trust-region strategy).
    ``max_iterations``: Ceres' ``max_num_iterations`` (step attempts). The tolerances are
    Ceres' (``function_tolerance``, ``parameter_tolerance``, ``gradient_tolerance``), far
    below COLMAP's. ``num_threads``: Ceres' threads (1 by default, to time one core).
    ``verbose``: echo the captured table and report on stderr afterwards.

    Returns a ``BALRunResult(backend="ceres")``: ``params`` the BAL state at the solution;
    ``initial_chi2`` / ``final_chi2`` OUR ``sum |r|^2`` over all observations;
    ``peer_initial_cost`` / ``peer_final_cost`` Ceres' cost at iteration 0 and at its last
    successful one (7 digits, from the table); ``seconds`` the ``bundle_adjustment`` call
    (building the Ceres problem and the filtering included, the conversions excluded);
    ``iterations`` the last row of the table (Ceres' step attempts). The trace: one record per
    row, ``chi2 = 2 *`` the cost Ceres prints, over the observations it kept (not ours:
    COLMAP's intermediate states are not reachable; for a rejected step, the rejected
    candidate's), ``damping`` the inverse trust-region radius
    (Ceres' mu), ``rho`` its ratio, ``accepted`` ratio > Ceres' ``min_relative_decrease``,
    ``seconds`` Ceres' total time.
    """
    peers.require("pycolmap")
    import pycolmap

    check_method(method, METHODS, "pycolmap")
    max_iterations = check_max_iterations(max_iterations)
    reconstruction, point_ids = to_reconstruction(problem)
    num_observations = reconstruction.compute_num_observations()
    options = _options(method, max_iterations, function_tolerance, parameter_tolerance, gradient_tolerance,
                       num_threads)
    min_relative_decrease = float(options.ceres.solver_options.min_relative_decrease)

    _no_glog_files()
    with captured_output() as log:
        start = time.perf_counter()
        pycolmap.bundle_adjustment(reconstruction, options)
        seconds = time.perf_counter() - start
    if verbose:
        print(log["stdout"] + log["stderr"], file=sys.stderr)

    cameras, points, kept = from_reconstruction(problem, reconstruction, point_ids)
    rows = parse_iterations(log["stdout"])
    trace, peer_costs, last_cost = _trace(rows, min_relative_decrease)
    iterations, reason = _stop_reason(rows, parse_report(log["stderr"]), method, max_iterations)
    initial_chi2 = 2.0 * cost(problem)
    return BALRunResult(
        backend="ceres", method=method, params=pack(cameras, points),
        initial_chi2=initial_chi2, final_chi2=2.0 * cost(problem, cameras, points),
        iterations=int(iterations), seconds=seconds, trace=trace, stop_reason=reason,
        initial_cost=0.5 * initial_chi2, final_cost=cost(problem, cameras, points),
        peer_initial_cost=peer_costs[0] if peer_costs else float("nan"), peer_final_cost=last_cost,
        peer_costs=peer_costs, peer_cost=PEER_COST,
        removed_points=int(np.count_nonzero(~kept)),
        removed_observations=int(num_observations - reconstruction.compute_num_observations()),
        behind_camera_start=behind_camera(problem), behind_camera_final=behind_camera(problem, cameras, points),
    )


def _options(method, max_iterations, function_tolerance, parameter_tolerance, gradient_tolerance, num_threads):
    """COLMAP's ``BundleAdjustmentOptions`` for ``solve``: the BAL camera's parameters refined but
    the principal point, Ceres' ``method`` and tolerances, and its per-iteration table printed."""
    import pycolmap

    options = pycolmap.BundleAdjustmentOptions()
    options.refine_principal_point = False
    options.refine_focal_length = True
    options.refine_extra_params = True
    options.print_summary = True
    solver = options.ceres.solver_options
    solver.num_threads = int(num_threads)
    solver.max_num_iterations = max_iterations
    solver.function_tolerance = function_tolerance
    solver.parameter_tolerance = parameter_tolerance
    solver.gradient_tolerance = gradient_tolerance
    strategies = {"levenberg-marquardt": "LEVENBERG_MARQUARDT", "dogleg": "DOGLEG"}
    pyceres = pycolmap._core.pyceres  # the Ceres enums pycolmap carries (not the pyceres package)
    solver.trust_region_strategy_type = getattr(pyceres.TrustRegionStrategyType, strategies[method])
    solver.minimizer_progress_to_stdout = True
    solver.logging_type = pyceres.LoggingType.PER_MINIMIZER_ITERATION
    return options


def _no_glog_files() -> None:
    """Unless ``pycolmap.logging.log_dir`` is set, no glog file per process in the temporary folder
    (glog's default)."""
    import pycolmap

    logging = pycolmap.logging
    if not logging.log_dir:
        for level in (logging.INFO, logging.WARNING, logging.ERROR):
            logging.set_log_destination(level, "")


def _trace(rows: list[dict], min_relative_decrease: float) -> tuple[list, list, float]:
    """``(trace, peer_costs, last accepted cost)`` from the rows of Ceres' table (see ``solve``)."""
    trace, peer_costs, last_cost = [], [], float("nan")
    for row in rows:
        accepted = row["iteration"] == 0 or row["tr_ratio"] > min_relative_decrease
        if accepted:
            last_cost = row["cost"]
        trace.append(IterationRecord(
            iteration=row["iteration"], chi2=2.0 * row["cost"],
            damping=1.0 / row["tr_radius"] if row["tr_radius"] > 0 else float("nan"),
            rho=row["tr_ratio"] if row["iteration"] > 0 else float("nan"),
            step_norm=row["step"] if row["iteration"] > 0 else float("nan"),
            accepted=accepted, seconds=row["total_time"]))
        peer_costs.append(row["cost"])
    return trace, peer_costs, last_cost


def _stop_reason(rows: list[dict], report: dict, method: str, max_iterations: int) -> tuple[int, str]:
    """``(iterations, stop_reason)`` from Ceres' table and COLMAP's report."""
    iterations = rows[-1]["iteration"] if rows else max(report.get("iterations", 1) - 1, 0)
    termination = report.get("termination", "unknown (no COLMAP report captured)")
    reason = f"{termination.lower()}: Ceres {method}, {iterations} iterations"
    if termination == "NO_CONVERGENCE":
        reason = f"max_iterations: {max_iterations} reached"
    if not rows:
        reason += "; Ceres' per-iteration table was not captured (no trace)"
    return iterations, reason
