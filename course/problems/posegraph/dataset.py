"""2D pose-graph datasets: TORO and g2o readers and writers, a Manhattan-world
generator, and named datasets.

File formats (one record a line, fields split on whitespace)::

    VERTEX2    id x y theta                                     (TORO)
    EDGE2      id1 id2 dx dy dtheta I11 I12 I22 I33 I13 I23     (TORO)
    VERTEX_SE2 id x y theta                                     (g2o)
    EDGE_SE2   id1 id2 dx dy dtheta I11 I12 I13 I22 I23 I33     (g2o, upper triangle)
    FIX        id [id ...]                                      (g2o)
    EQUIV      a b                                              (TORO; skipped, counted)

An edge ``id1 id2`` measures pose ``id2`` in the frame of pose ``id1``, whichever id
is larger. Blank lines and lines starting with ``#`` are skipped. A TORO dataset may
be split into ``<name>-v.dat`` (vertices) and ``<name>-e.dat`` (edges).

Named datasets (``load_dataset``, ``list_datasets``) come from the data folder
(``data_dir()``: ``$COURSE_DATA``, else ``<repo>/../shared/data``), from the gtsam
wheel's ``Data/`` folder (found without importing gtsam), or from the generator
``manhattan:N[:seed]``.
"""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from course.core.data import DatasetInfo, locate, origin
from course.core.errors import DatasetError
from course.geometry import se2 as geometry
from course.problems.posegraph.graph import PoseGraph
from course.solver.information import HINT, NoInformationError, check_mode, eigenvalues_text, not_definite, repair

log = logging.getLogger(__name__)


# ---------------------------------------------------------------------------------------
# Reading

_FIELDS = {
    "VERTEX2": ("id", "x", "y", "theta"),
    "VERTEX_SE2": ("id", "x", "y", "theta"),
    "EDGE2": ("id1", "id2", "dx", "dy", "dtheta", "I11", "I12", "I22", "I33", "I13", "I23"),
    "EDGE_SE2": ("id1", "id2", "dx", "dy", "dtheta", "I11", "I12", "I13", "I22", "I23", "I33"),
}
# (rows, cols) of an edge's six information values, in file order.
_INFO_CELLS = {
    "EDGE2": (np.array([0, 0, 1, 2, 0, 1]), np.array([0, 1, 1, 2, 2, 2])),
    "EDGE_SE2": (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2])),
}


class _Records:
    """Raw records collected from one or more files, in file order."""

    def __init__(self):
        self.vertex_ids, self.vertex_tokens, self.vertex_where = [], [], []
        self.edge_ids, self.edge_tokens, self.edge_where, self.edge_tags = [], [], [], []
        self.fixed, self.fixed_where = [], []
        self.equiv = 0  # EQUIV lines skipped
        self.first_line = {}  # vertex id -> (path, line)

    def read(self, path: Path):
        for lineno, line in enumerate(_open(path), 1):
            parts = line.split()
            if not parts or parts[0].startswith("#"):
                continue
            tag, where = parts[0], (path, lineno)
            if tag in _FIELDS:
                self._record(tag, parts, where)
            elif tag == "FIX":
                if len(parts) < 2:
                    _fail(where, "FIX line has no vertex id")
                for tok in parts[1:]:
                    self.fixed.append(_int(tok, "id", where))
                    self.fixed_where.append(where)
            elif tag == "EQUIV":
                self.equiv += 1
            else:
                known = ", ".join([*_FIELDS, "FIX", "EQUIV"])
                _fail(where, f"unknown tag {tag!r} (known: {known})")

    def _record(self, tag, parts, where):
        names = _FIELDS[tag]
        if len(parts) - 1 != len(names):
            _fail(where, f"{tag} line has {len(parts) - 1} values, expected {len(names)} "
                         f"({' '.join(names)})")
        if tag in _INFO_CELLS:
            self.edge_ids.append((_int(parts[1], "id1", where), _int(parts[2], "id2", where)))
            self.edge_tokens.append(parts[3:])
            self.edge_where.append(where)
            self.edge_tags.append(tag)
        else:
            vid = _int(parts[1], "id", where)
            if vid in self.first_line:
                p, n = self.first_line[vid]
                _fail(where, f"duplicate vertex id {vid} (first defined at {p}:{n})")
            self.first_line[vid] = where
            self.vertex_ids.append(vid)
            self.vertex_tokens.append(parts[2:])
            self.vertex_where.append(where)

    def graph(self, name: str, source: str, information: str = "strict") -> PoseGraph:
        if not self.vertex_ids:
            raise DatasetError(f"{source}: no vertices (empty graph)")
        poses = _floats(self.vertex_tokens, self.vertex_where,
                        [_FIELDS["VERTEX2"][1:]] * len(self.vertex_tokens), 3)
        index = {vid: k for k, vid in enumerate(self.vertex_ids)}
        edges = np.empty((len(self.edge_ids), 2), dtype=np.int64)
        for k, (a, b) in enumerate(self.edge_ids):
            for col, vid in enumerate((a, b)):
                if vid not in index:
                    _fail(self.edge_where[k], f"edge refers to missing vertex id {vid}")
                edges[k, col] = index[vid]
        names = [_FIELDS[t][2:] for t in self.edge_tags]
        values = _floats(self.edge_tokens, self.edge_where, names, 9)
        info = np.zeros((len(values), 3, 3))
        tags = np.array(self.edge_tags, dtype=object)
        for tag, (rows, cols) in _INFO_CELLS.items():
            block = np.zeros((np.sum(tags == tag), 3, 3))
            block[:, rows, cols] = block[:, cols, rows] = values[tags == tag, 3:]
            info[tags == tag] = block
        info, repaired = _checked_information(info, self.edge_where, self.edge_tags, information)
        fixed = []
        for vid, where in zip(self.fixed, self.fixed_where):
            if vid not in index:
                _fail(where, f"FIX refers to missing vertex id {vid}")
            if index[vid] not in fixed:
                fixed.append(index[vid])
        if self.equiv:
            log.info("%s: skipped %d EQUIV lines", source, self.equiv)
        return PoseGraph(
            poses, edges[:, 0], edges[:, 1], values[:, :3], info,
            fixed=np.array(fixed or [0]), ids=np.array(self.vertex_ids, dtype=np.int64),
            name=name, source=source, repaired=repaired, information_repair=information,
        )


def _open(path: Path):
    if not path.is_file():
        what = "is not a file" if path.exists() else "does not exist"
        raise DatasetError(f"{path}: {what}")
    with open(path, encoding="utf-8", errors="replace") as f:
        yield from f


def _fail(where, problem):
    path, lineno = where
    raise DatasetError(f"{path}:{lineno}: {problem}")


def _int(token, field, where):
    try:
        return int(token)
    except ValueError:
        _fail(where, f"field {field} is not an integer: {token!r}")


def _floats(rows, where, names, width) -> np.ndarray:
    """``rows`` (list of lists of str) -> (len(rows), width) floats; on a bad token, name
    its field (``names[k]`` are row k's field names)."""
    try:
        values = np.array(rows, dtype=float).reshape(len(rows), width)
    except ValueError:
        values = None
    if values is not None and np.isfinite(values).all():
        return values
    for k, row in enumerate(rows):
        for field, token in zip(names[k], row):
            try:
                ok = np.isfinite(float(token))
            except ValueError:
                ok = False
            if not ok:
                _fail(where[k], f"field {field} is not a finite number: {token!r}")
    raise AssertionError("unreachable")


#: the blocks (translation, rotation) that ``information="isotropic"`` makes scaled identities
_BLOCKS = ((0, 1), (2,))


def _checked_information(info, where, tags, mode):
    """``(info, repaired)``: the (M, 3, 3) information matrices with those that are not positive
    definite refused (``strict``: the first one's file, line and eigenvalues) or repaired
    (:func:`course.solver.information.repair`), and the (M,) mask of the repaired ones."""
    bad = not_definite(info)
    if mode == "strict" and bad.any():
        k = int(np.flatnonzero(bad)[0])
        order = " ".join(_FIELDS[tags[k]][5:])
        _fail(where[k], f"information matrix is not symmetric positive definite "
                        f"(eigenvalues {eigenvalues_text(info[k])}; {tags[k]} order is {order}): {info[k].tolist()}; "
                        f"{HINT}")
    try:
        return repair(info, mode, _BLOCKS)
    except NoInformationError as exc:
        _fail(where[exc.index], str(exc))
        raise AssertionError("unreachable") from exc


def _toro_pair(path: Path) -> tuple[Path, Path] | None:
    """``(vertices, edges)`` if ``path`` is ``X-v.dat``, ``X-e.dat`` or the prefix ``X``."""
    s = str(path)
    for suffix in ("-v.dat", "-e.dat"):
        if s.endswith(suffix):
            return Path(s[: -len(suffix)] + "-v.dat"), Path(s[: -len(suffix)] + "-e.dat")
    if not path.exists() and Path(s + "-v.dat").is_file():
        return Path(s + "-v.dat"), Path(s + "-e.dat")
    return None


def read_graph(path, name: str | None = None, information: str = "strict") -> PoseGraph:
    """Read a TORO or g2o 2D pose graph.

    ``path`` is a single file (the tags decide the format: ``VERTEX2``/``EDGE2`` are
    TORO, ``VERTEX_SE2``/``EDGE_SE2``/``FIX`` are g2o), or a TORO pair given as
    ``X-v.dat``, ``X-e.dat`` or the prefix ``X``. Fixed vertices are the ``FIX`` ids,
    else index 0. ``EQUIV`` lines are skipped and their count is logged at INFO level.
    Raises ``DatasetError`` naming the file and line of the first problem.

    ``information`` (:mod:`course.solver.information`): ``strict`` refuses an edge whose
    information is not positive definite (its eigenvalues and the tag's field order in the
    message: a TORO file written in g2o's order shows this way); ``nearest-psd`` replaces its
    matrix by the nearest one whose eigenvalues are at least 1e-9 times its largest,
    ``isotropic`` by SE-Sync's ``diag(tau, tau, kappa)`` (``tau = 2 / tr(Omega_xy^-1)``, kappa
    the rotation's entry). Both repair those edges alone; the graph's ``repaired`` marks them and
    its ``information_repair`` names the option.
    """
    check_mode(information)
    path = Path(path)
    records = _Records()
    pair = _toro_pair(path)
    if pair:
        for p in pair:
            records.read(p)
        stem, source = pair[0].name[: -len("-v.dat")], f"{pair[0]} + {pair[1]}"
    else:
        records.read(path)
        stem, source = path.stem, str(path)
    return records.graph(name or stem, source, information)


# ---------------------------------------------------------------------------------------
# Writing


def _numbers(a) -> list[str]:
    """Rows of ``a`` as space-joined shortest round-trip floats."""
    return [" ".join(map(repr, row)) for row in np.asarray(a, dtype=float).tolist()]


def _write(graph: PoseGraph, path, vertex_tag, edge_tag, fix: bool):
    ids = np.asarray(graph.ids, dtype=np.int64)
    rows, cols = _INFO_CELLS[edge_tag]
    info = np.asarray(graph.information)[:, rows, cols]
    lines = [f"{vertex_tag} {i} {v}" for i, v in zip(ids.tolist(), _numbers(graph.poses))]
    lines += [
        f"{edge_tag} {a} {b} {z} {w}"
        for a, b, z, w in zip(ids[graph.edges_i].tolist(), ids[graph.edges_j].tolist(),
                              _numbers(graph.measurements), _numbers(info))
    ]
    if fix:  # last: gtsam's readG2o stops reading edges at a FIX line before them
        lines += [f"FIX {i}" for i in ids[graph.fixed].tolist()]
    Path(path).write_text("\n".join(lines) + "\n")


def write_g2o(graph: PoseGraph, path) -> None:
    """Write ``VERTEX_SE2``, ``EDGE_SE2`` and then ``FIX`` (for ``graph.fixed``) lines.

    Uses the file ids ``graph.ids`` and the upper triangle of each information matrix.
    Floats are written at round-trip precision, so ``read_graph`` gives back the arrays.
    """
    _write(graph, path, "VERTEX_SE2", "EDGE_SE2", fix=True)


def write_toro(graph: PoseGraph, path) -> None:
    """Write one TORO file (``VERTEX2``, ``EDGE2`` with I11 I12 I22 I33 I13 I23).

    TORO has no FIX record: a reader fixes the first vertex.
    """
    _write(graph, path, "VERTEX2", "EDGE2", fix=False)


# ---------------------------------------------------------------------------------------
# Manhattan-world generator


def manhattan(num_poses: int, seed: int = 0, *, grid: int | None = None,
              sigma_xy: float = 0.05, sigma_theta: float = 0.01,
              turn_prob: float = 0.3, closures_per_pose: int = 2) -> PoseGraph:
    """A synthetic Manhattan-world pose graph with ground truth.

    A robot on a ``grid x grid`` lattice of unit cells (default ``max(3, round(sqrt(N)/2))``)
    steps one unit forward, then turns by +-90 degrees with probability ``turn_prob``
    (always when the next step would leave the grid), so it revisits cells. Edges:
    odometry between consecutive poses, and loop closures from each pose to at most
    ``closures_per_pose`` earlier poses (chosen at random) in the same cell.
    Measurements are the true relative pose plus Gaussian noise (``sigma_xy`` metres,
    ``sigma_theta`` radians); information is ``diag(1/sigma_xy^2, 1/sigma_xy^2,
    1/sigma_theta^2)``. The initial estimate composes the noisy odometry from the true
    first pose, so it drifts. Deterministic for given arguments.

    Returns a PoseGraph with ``poses`` (N, 3) and ``ground_truth`` (N, 3).
    """
    if num_poses < 2:
        raise ValueError(f"manhattan needs at least 2 poses, got {num_poses}")
    rng = np.random.default_rng(seed)
    size = grid or max(3, int(round(np.sqrt(num_poses) / 2)))
    step = {0: (1, 0), 1: (0, 1), 2: (-1, 0), 3: (0, -1)}  # heading in quarter turns

    cells, headings = [(0, 0)], [0]
    for _ in range(num_poses - 1):
        (x, y), h = cells[-1], headings[-1]
        x, y = x + step[h][0], y + step[h][1]
        allowed = [t for t in (-1, 0, 1)  # turns after which the next step stays inside
                   if 0 <= x + step[(h + t) % 4][0] < size
                   and 0 <= y + step[(h + t) % 4][1] < size]
        turn = int(rng.choice([-1, 1])) if rng.random() < turn_prob else 0
        if turn not in allowed:
            turn = int(rng.choice(allowed))
        cells.append((x, y))
        headings.append((h + turn) % 4)

    truth = np.column_stack([np.array(cells, dtype=float),
                             geometry.wrap_angle(np.array(headings) * np.pi / 2)])
    pairs = [(k, k + 1) for k in range(num_poses - 1)]
    visits: dict[tuple[int, int], list[int]] = {}
    for k, cell in enumerate(cells):
        earlier = visits.setdefault(cell, [])
        chosen = rng.choice(earlier, size=min(closures_per_pose, len(earlier)), replace=False)
        pairs += [(int(j), k) for j in sorted(chosen)]
        earlier.append(k)

    ei, ej = np.array(pairs).T
    sigma = np.array([sigma_xy, sigma_xy, sigma_theta])
    z = geometry.between(truth[ei], truth[ej]) + rng.normal(size=(len(ei), 3)) * sigma
    z[:, 2] = geometry.wrap_angle(z[:, 2])
    poses = [truth[0]]
    for k in range(num_poses - 1):
        poses.append(geometry.compose(poses[-1], z[k]))
    info = np.broadcast_to(np.diag(1.0 / sigma**2), (len(ei), 3, 3)).copy()
    return PoseGraph(
        np.array(poses), ei, ej, z, info, fixed=np.array([0]), name=f"manhattan:{num_poses}:{seed}",
        source=f"course.problems.posegraph.dataset.manhattan({num_poses}, seed={seed})", ground_truth=truth,
    )


# ---------------------------------------------------------------------------------------
# Named datasets


# name -> (folder: "data" or "gtsam", relative path (a TORO pair as its prefix), format,
#          documented poses, documented edges)
_NAMED = {
    "intel": ("data", "intel_toro/intel", "toro pair", 729, 3070),
    "test_quadrat": ("data", "test_quadrat/test_quadrat", "toro pair", 4, 5),
    "intel-g2o": ("data", "intel_carlone/input_INTEL_g2o.g2o", "g2o", 1228, 1483),
    "m3500": ("data", "m3500/input_M3500_g2o.g2o", "g2o", 3500, 5453),
    "mit": ("data", "mit/input_MITb_g2o.g2o", "g2o", 808, 827),
    "csail": ("data", "csail/CSAIL_P_toro.graph", "toro", 1045, 1172),
    "fr079": ("data", "fr079/FR079_P_toro.graph", "toro", 989, 1217),
    "w100": ("gtsam", "w100.graph", "toro", 100, 300),
    "w10000": ("gtsam", "w10000.graph", "toro", 10000, 64311),
}


def _locate(name: str) -> Path:
    """The path of a named dataset (a TORO pair as its prefix); DatasetError if absent."""
    where, rel, *_ = _NAMED[name]
    return locate(f"dataset {name!r}", where, rel, lambda path: path.is_file() or Path(f"{path}-v.dat").is_file())


def dataset_names() -> list:
    """The names ``load_dataset`` knows (besides ``manhattan:N`` and file paths)."""
    return list(_NAMED)


def list_datasets() -> list[DatasetInfo]:
    """All named datasets, with documented sizes and whether each can be loaded here."""
    out = []
    for name, (where, rel, fmt, n, m) in _NAMED.items():
        try:
            _locate(name)
            out.append(DatasetInfo(name, n, m, fmt, origin(where, rel), True))
        except DatasetError as e:
            out.append(DatasetInfo(name, n, m, fmt, origin(where, rel), False, getattr(e, "short", str(e))))
    out.append(DatasetInfo("manhattan:N[:seed]", None, None, "synthetic",
                           "generator course.problems.posegraph.dataset.manhattan", True))
    return out


def load_dataset(name: str, information: str = "strict") -> PoseGraph:
    """Load a named dataset (see ``list_datasets``), ``manhattan:N[:seed]``, or a file path;
    ``information`` (the repair of an information matrix that is not positive definite) as in
    :func:`read_graph` (the generator's are all definite)."""
    check_mode(information)
    if name in _NAMED:
        return read_graph(_locate(name), name=name, information=information)
    if name.startswith("manhattan:"):
        parts = name.split(":")[1:]
        try:
            if not 1 <= len(parts) <= 2:
                raise ValueError
            numbers = [int(p) for p in parts]
        except ValueError:
            raise DatasetError(f"bad generator name {name!r}: use manhattan:N or "
                               "manhattan:N:seed") from None
        return manhattan(*numbers)
    if Path(name).is_file() or _toro_pair(Path(name)):
        return read_graph(name, information=information)
    known = ", ".join([*_NAMED, "manhattan:N[:seed]"])
    raise DatasetError(f"unknown dataset {name!r} and no such file; known names: {known}")
