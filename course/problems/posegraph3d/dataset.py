"""3D pose-graph datasets: the g2o SE(3) and ``.graph`` readers, a g2o writer, and named graphs.

File formats (one record a line, fields split on whitespace; blank lines and ``#`` skipped)::

    VERTEX_SE3:QUAT id x y z qx qy qz qw
    EDGE_SE3:QUAT   id1 id2 x y z qx qy qz qw I(21)     upper triangle of the 6x6 information,
                                                        row by row, order (x, y, z, rx, ry, rz)
    VERTEX3         id x y z roll pitch yaw              R = Rz(yaw) Ry(pitch) Rx(roll)
    EDGE3           id1 id2 x y z roll pitch yaw [I(21)] without I: the identity
    FIX             id [id ...]

An edge ``id1 id2`` measures pose ``id2`` in the frame of pose ``id1``. Quaternions are
normalised (files give them to 6 digits). The information in a file is for g2o's error
``[D_t; vec(q)]`` (its rotation entries are about 4x those of the angle's, e.g. 400 for a
0.1 rad rotation noise); the reader converts it to ours, ``[D_t; Log(D_R)]`` (see
:data:`course.geometry.se3.G2O_SCALE`), and the writer converts it back, so a file read and
written gives back its numbers. ``EDGE3`` lines carry no information in the gtsam wheel's
``sphere_smallnoise.graph``: the identity is used there, for our error.

A file with edges and no vertices is read too: the poses then start from the edges composed
along a breadth-first spanning tree from the first vertex named, unreached vertices at the
identity.

Named graphs (``load_dataset``): the data folder's ``se3/`` graphs, the gtsam wheel's
``sphere_smallnoise`` and ``pose3example``, and any file path.
"""

from __future__ import annotations

from collections import deque
from pathlib import Path

import numpy as np

from course.core.data import DatasetInfo, locate, origin
from course.core.errors import DatasetError
from course.geometry import quaternion, se3
from course.problems.posegraph3d.graph import PoseGraph3D
from course.solver.information import HINT, NoInformationError, check_mode, eigenvalues_text, not_definite, repair

_POSE_QUAT = ("x", "y", "z", "qx", "qy", "qz", "qw")
_POSE_EULER = ("x", "y", "z", "roll", "pitch", "yaw")
_INFO = tuple(f"I{a}{b}" for a in range(1, 7) for b in range(a, 7))
_VERTICES = {"VERTEX_SE3:QUAT": _POSE_QUAT, "VERTEX3": _POSE_EULER}
_EDGES = {"EDGE_SE3:QUAT": _POSE_QUAT, "EDGE3": _POSE_EULER}
#: the upper triangle of a 6x6 matrix, row by row (the file's order)
_UPPER = np.triu_indices(6)


def _fail(path, lineno, problem):
    raise DatasetError(f"{path}:{lineno}: {problem}")


def _numbers(rows, names, path, lines, width) -> np.ndarray:
    """``rows`` (lists of str, each of ``width``) as floats (K, width) in one conversion; on a
    bad token, the file, line and field (``names[k]``: row k's field names)."""
    try:
        values = np.array(rows, dtype=float).reshape(len(rows), width)
        if np.isfinite(values).all():
            return values
    except ValueError:
        pass
    for row, row_names, lineno in zip(rows, names, lines):
        for name, token in zip(row_names, row):
            try:
                ok = np.isfinite(float(token))
            except ValueError:
                ok = False
            if not ok:
                _fail(path, lineno, f"field {name} is not a finite number: {token!r}")
    raise AssertionError("unreachable")


def _int(token, name, path, lineno) -> int:
    try:
        return int(token)
    except ValueError:
        raise DatasetError(f"{path}:{lineno}: field {name} is not an integer: {token!r}") from None


def _rotations(values: np.ndarray, quat: np.ndarray, where: list, path) -> np.ndarray:
    """Rotations of rows whose last fields are a quaternion (``quat``) or Euler angles."""
    R = np.empty((len(values), 3, 3))
    if quat.any():
        q = values[quat, 3:7]
        norms = np.linalg.norm(q, axis=1)
        if (norms < 1e-6).any():
            k = np.flatnonzero(quat)[int(np.argmax(norms < 1e-6))]
            _fail(path, where[k], f"quaternion (qx, qy, qz, qw) has norm {np.linalg.norm(values[k, 3:7]):g}")
        R[quat] = quaternion.to_matrix(q)
    if (~quat).any():
        R[~quat] = se3.euler_to_matrix(*values[~quat, 3:6].T)
    return R


def read_graph(path, name: str | None = None, information: str = "strict") -> PoseGraph3D:
    """Read a g2o SE(3) or ``.graph`` 3D pose graph (formats in the module docstring).

    Fixed vertices are the ``FIX`` ids, else the first. Raises ``DatasetError`` naming the
    file, line and field of the first problem: an unknown tag, a wrong field count, a
    number that is not one, a duplicate vertex, an edge to a missing vertex, a zero
    quaternion, an information matrix that is not positive definite (with its eigenvalues,
    in the file's units).

    ``information`` (:mod:`course.solver.information`): ``strict`` refuses an edge
    whose information is not positive definite; ``nearest-psd`` replaces its matrix by the
    nearest one whose eigenvalues are at least 1e-9 times its largest, ``isotropic`` by
    SE-Sync's scaled identity per block (translation, rotation). Both repair those edges
    alone, in the file's units, before the conversion to our error; the graph's ``repaired``
    marks them and its ``information_repair`` names the option.
    """
    check_mode(information)
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: {'is not a file' if path.exists() else 'does not exist'}")
    vertex_ids, vertex_values, vertex_flags, vertex_lines = [], [], [], []
    first: dict[int, int] = {}
    edge_ids, edge_values, edge_flags, edge_info, edge_lines = [], [], [], [], []
    fixed, fixed_lines = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for lineno, line in enumerate(f, 1):
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            tag = parts[0]
            if tag in _VERTICES:
                names = ("id", *_VERTICES[tag])
                if len(parts) - 1 != len(names):
                    _fail(path, lineno, f"{tag} line has {len(parts) - 1} values, expected {len(names)} "
                                        f"({' '.join(names)})")
                vid = _int(parts[1], "id", path, lineno)
                if vid in first:
                    _fail(path, lineno, f"duplicate vertex id {vid} (first defined at line {first[vid]})")
                first[vid] = lineno
                vertex_ids.append(vid)
                vertex_values.append(parts[2:] + ["0"] * (tag == "VERTEX3"))
                vertex_flags.append(tag == "VERTEX_SE3:QUAT")
                vertex_lines.append(lineno)
            elif tag in _EDGES:
                names = ("id1", "id2", *_EDGES[tag], *_INFO)
                bare = tag == "EDGE3" and len(parts) - 1 == len(names) - len(_INFO)
                if len(parts) - 1 != len(names) and not bare:
                    _fail(path, lineno, f"{tag} line has {len(parts) - 1} values, expected {len(names)} "
                                        f"({' '.join(names[:2 + len(_EDGES[tag])])} and the 21 of the information)")
                edge_ids.append((_int(parts[1], "id1", path, lineno), _int(parts[2], "id2", path, lineno)))
                pose_fields = len(_EDGES[tag])
                edge_values.append(parts[3:3 + pose_fields] + ["0"] * (tag == "EDGE3"))
                edge_info.append(None if bare else parts[3 + pose_fields:])
                edge_flags.append(tag == "EDGE_SE3:QUAT")
                edge_lines.append(lineno)
            elif tag == "FIX":
                if len(parts) < 2:
                    _fail(path, lineno, "FIX line has no vertex id")
                for token in parts[1:]:
                    fixed.append(_int(token, "id", path, lineno))
                    fixed_lines.append(lineno)
            else:
                _fail(path, lineno, f"unknown tag {tag!r} (known: {', '.join([*_VERTICES, *_EDGES, 'FIX'])})")
    if not vertex_ids and not edge_ids:
        raise DatasetError(f"{path}: no vertices and no edges (empty graph)")
    if not vertex_ids:  # edges only: every vertex named by an edge, in order of appearance
        vertex_ids = list(dict.fromkeys(v for pair in edge_ids for v in pair))
    index = {vid: k for k, vid in enumerate(vertex_ids)}
    edges = np.empty((len(edge_ids), 2), dtype=np.int64)
    for k, pair in enumerate(edge_ids):
        for column, vid in enumerate(pair):
            if vid not in index:
                _fail(path, edge_lines[k], f"edge refers to missing vertex id {vid}")
            edges[k, column] = index[vid]
    edge_quat = np.array(edge_flags, dtype=bool)
    values = _numbers(edge_values, [_EDGES["EDGE_SE3:QUAT" if q else "EDGE3"] for q in edge_quat], path,
                      edge_lines, 7)
    R_z = _rotations(values, edge_quat, edge_lines, path)
    given = np.array([info is not None for info in edge_info], dtype=bool)
    matrices = np.tile(np.eye(6), (len(edge_ids), 1, 1))
    repaired = np.zeros(len(edge_ids), dtype=bool)
    if given.any():
        given_lines = [n for n, g in zip(edge_lines, given) if g]
        upper = _numbers([info for info in edge_info if info is not None], [_INFO] * int(given.sum()), path,
                         given_lines, 21)
        M = np.zeros((len(upper), 6, 6))
        M[:, _UPPER[0], _UPPER[1]] = upper
        M = M + np.triu(M, 1).transpose(0, 2, 1)
        M, repaired[given] = _checked_information(M, information, path, given_lines)
        matrices[given] = M / np.outer(se3.G2O_SCALE, se3.G2O_SCALE)
    if vertex_values:
        vertex_quat = np.array(vertex_flags, dtype=bool)
        pose_values = _numbers(vertex_values, [_POSE_QUAT if q else _POSE_EULER for q in vertex_quat], path,
                               vertex_lines, 7)
        t, R = pose_values[:, :3].copy(), _rotations(pose_values, vertex_quat, vertex_lines, path)
    else:
        t, R = compose_spanning_tree(len(vertex_ids), edges[:, 0], edges[:, 1], values[:, :3], R_z)
    fixed_index = []
    for vid, lineno in zip(fixed, fixed_lines):
        if vid not in index:
            _fail(path, lineno, f"FIX refers to missing vertex id {vid}")
        if index[vid] not in fixed_index:
            fixed_index.append(index[vid])
    return PoseGraph3D(t, R, edges[:, 0], edges[:, 1], values[:, :3], R_z, matrices,
                       fixed=np.array(fixed_index or [0]), ids=np.array(vertex_ids, dtype=np.int64),
                       name=name or path.stem, source=str(path), repaired=repaired, information_repair=information)


#: the blocks (translation, rotation) that ``information="isotropic"`` makes scaled identities
_BLOCKS = ((0, 1, 2), (3, 4, 5))


def _checked_information(M, mode, path, lines):
    """``(M, repaired)``: the (K, 6, 6) information matrices as the file gives them, with those that
    are not positive definite refused (``strict``: the first one's file, line and eigenvalues) or
    repaired (:func:`course.solver.information.repair`, in the file's units), and the mask of
    the repaired ones."""
    bad = not_definite(M)
    if mode == "strict" and bad.any():
        k = int(np.flatnonzero(bad)[0])
        _fail(path, lines[k], "information matrix is not symmetric positive definite (fields I11..I66, upper "
                              f"triangle row by row): eigenvalues {eigenvalues_text(M[k])}; {HINT}")
    try:
        return repair(M, mode, _BLOCKS)
    except NoInformationError as exc:
        _fail(path, lines[exc.index], str(exc))
        raise AssertionError("unreachable") from exc


def compose_spanning_tree(num_poses, edges_i, edges_j, t_z, R_z):
    """Poses ``(t (N, 3), R (N, 3, 3))`` from the measurements composed along a breadth-first
    spanning tree from vertex 0 (an edge walked backwards uses its inverse); vertices it does
    not reach stay at the identity."""
    t, R = np.zeros((num_poses, 3)), np.tile(np.eye(3), (num_poses, 1, 1))
    neighbours = [[] for _ in range(num_poses)]
    for k, (a, b) in enumerate(zip(edges_i.tolist(), edges_j.tolist())):
        neighbours[a].append((b, k, True))
        neighbours[b].append((a, k, False))
    seen = np.zeros(num_poses, dtype=bool)
    seen[0] = True
    queue = deque([0])
    while queue:
        a = queue.popleft()
        for b, k, forward in neighbours[a]:
            if seen[b]:
                continue
            seen[b] = True
            if forward:  # T_b = T_a Z
                t[b], R[b] = se3.compose(t[a], R[a], t_z[k], R_z[k])
            else:  # T_b = T_a Z^-1
                t[b], R[b] = se3.compose(t[a], R[a], -R_z[k].T @ t_z[k], R_z[k].T)
            queue.append(b)
    return t, R


def write_g2o(graph: PoseGraph3D, path) -> None:
    """Write ``VERTEX_SE3:QUAT``, ``EDGE_SE3:QUAT`` (information converted back to g2o's error)
    and ``FIX`` lines, with the file ids, floats at round-trip precision."""
    ids = np.asarray(graph.ids, dtype=np.int64)

    def rows(a):
        return [" ".join(map(repr, row)) for row in np.asarray(a, dtype=float).tolist()]

    poses = np.concatenate([graph.t, quaternion.from_matrix(graph.R)], axis=1)
    measurements = np.concatenate([graph.t_z, quaternion.from_matrix(graph.R_z)], axis=1)
    info = (graph.information * np.outer(se3.G2O_SCALE, se3.G2O_SCALE))[:, _UPPER[0], _UPPER[1]]
    lines = [f"VERTEX_SE3:QUAT {i} {p}" for i, p in zip(ids.tolist(), rows(poses))]
    lines += [f"EDGE_SE3:QUAT {a} {b} {z} {w}" for a, b, z, w in zip(
        ids[graph.edges_i].tolist(), ids[graph.edges_j].tolist(), rows(measurements), rows(info))]
    lines += [f"FIX {i}" for i in ids[graph.fixed].tolist()]
    Path(path).write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------
# Named graphs

# name -> (folder: "data" or "gtsam", relative path, format, documented poses, edges)
_NAMED = {
    "sphere2500": ("data", "se3/sphere2500.g2o", "g2o SE3", 2500, 4949),
    "torus3D": ("data", "se3/torus3D.g2o", "g2o SE3", 5000, 9048),
    "parking-garage": ("data", "se3/parking-garage.g2o", "g2o SE3", 1661, 6275),
    "smallGrid3D": ("data", "se3/smallGrid3D.g2o", "g2o SE3", 125, 297),
    "tinyGrid3D": ("data", "se3/tinyGrid3D.g2o", "g2o SE3", 9, 11),
    "sphere_smallnoise": ("gtsam", "sphere_smallnoise.graph", "graph Euler", 2200, 8647),
    "pose3example": ("gtsam", "pose3example.txt", "g2o SE3", 5, 6),
}


#: ground truth where it is known: the gtsam wheel's noise-free edges of sphere2500, composed from
#: pose 0 at the origin (as the file's pose 0)
_TRUTH = {"sphere2500": ("gtsam", "sphere2500_groundtruth.txt")}


def ground_truth(name: str):
    """``(t (N, 3), R (N, 3, 3))`` of a named graph's true poses, or None where unknown or absent
    (the truth of sphere2500 ships with gtsam)."""
    if name not in _TRUTH:
        return None
    try:
        truth = read_graph(locate(f"the truth of {name!r}", *_TRUTH[name]))
    except DatasetError:
        return None
    order = np.argsort(np.asarray(truth.ids))  # ids 0..N-1 in the file's order of appearance: put them in id order
    return truth.t[order], truth.R[order]


def dataset_names() -> list:
    """The names ``load_dataset`` knows (besides file paths)."""
    return list(_NAMED)


def list_datasets() -> list[DatasetInfo]:
    """Every named 3D graph, with documented sizes and whether it can be loaded here."""
    out = []
    for name, (where, rel, fmt, n, m) in _NAMED.items():
        try:
            locate(f"dataset {name!r}", where, rel)
            out.append(DatasetInfo(name, n, m, fmt, origin(where, rel), True))
        except DatasetError as e:
            out.append(DatasetInfo(name, n, m, fmt, origin(where, rel), False, getattr(e, "short", str(e))))
    return out


def load_dataset(name: str, information: str = "strict") -> PoseGraph3D:
    """A named 3D graph (``dataset_names``) or a file path; ``information`` (the repair of an
    information matrix that is not positive definite) as in :func:`read_graph`."""
    if name in _NAMED:
        where, rel, *_ = _NAMED[name]
        graph = read_graph(locate(f"dataset {name!r}", where, rel), name=name, information=information)
        graph.ground_truth = ground_truth(name)
        return graph
    if Path(name).is_file():
        return read_graph(name, information=information)
    raise DatasetError(f"unknown 3D dataset {name!r} and no such file; known names: {', '.join(_NAMED)}")
