"""Information matrices that are not positive definite: refused by default, repaired on request
(``information="nearest-psd"`` or ``"isotropic"``, ``course.solver.information``), counted, and
said on every row of ``compare``."""

import json
import subprocess
import sys

import numpy as np
import pytest

from course.app import compare
from course.app.cli import INFORMATION, main
from course.core.errors import DatasetError
from course.core.impl import REPO_ROOT
from course.geometry import quaternion, se3, so3
from course.problems.posegraph import dataset as datasets2d
from course.problems.posegraph3d import dataset as datasets3d
from course.problems.posegraph3d.problem import PoseGraph3DProblem
from course.solver import information
from course.solver.minimizer import minimize

RNG = np.random.default_rng(34)
#: a definite information in the file's units (g2o's error), with correlations
GOOD = np.diag([100.0, 120.0, 90.0, 400.0, 500.0, 450.0])
GOOD[0, 1] = GOOD[1, 0] = 10.0
GOOD[2, 4] = GOOD[4, 2] = 20.0
#: indefinite: eigenvalues about -8.9e5 beside 1.8e7 (a cross term too large for its diagonal), both
#: diagonal blocks definite
BAD = np.diag([1.7e7, 1e6, 1e6, 400.0, 400.0, 400.0])
BAD[0, 3] = BAD[3, 0] = 4e6
#: the edge (0-based among the edges) that carries BAD, and its line in the file (4 vertices first)
BAD_EDGE, BAD_LINE = 2, 4 + 2 + 1


def _upper(M) -> str:
    return " ".join(repr(v) for v in M[np.triu_indices(6)].tolist())


def _graph_text(bad=BAD) -> str:
    """4 poses, the chain 0-1-2-3 and the loop closure 3-0; noisy measurements, a perturbed start;
    edge ``BAD_EDGE`` carries ``bad``."""
    t = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0.1], [0, 1, 0.1]])
    R = so3.exp_many(np.array([[0, 0, 0], [0, 0, np.pi / 2], [0, 0.05, np.pi], [0, 0, -np.pi / 2]]))
    lines = []
    for k in range(4):
        t0, R0 = t[k], R[k]
        if k:  # the first pose (fixed) where it is, the others moved
            t0, R0 = t0 + 0.1 * RNG.normal(size=3), R0 @ so3.so3_exp(0.05 * RNG.normal(size=3))
        q = quaternion.from_matrix(R0[None])[0]
        lines.append(f"VERTEX_SE3:QUAT {k} {' '.join(map(repr, np.r_[t0, q].tolist()))}")
    for e, (i, j) in enumerate(((0, 1), (1, 2), (2, 3), (3, 0))):
        t_z, R_z = se3.between(t[i], R[i], t[j], R[j])
        t_z, R_z = t_z + 0.01 * RNG.normal(size=3), R_z @ so3.so3_exp(0.01 * RNG.normal(size=3))
        q = quaternion.from_matrix(R_z[None])[0]
        lines.append(f"EDGE_SE3:QUAT {i} {j} {' '.join(map(repr, np.r_[t_z, q].tolist()))} "
                     f"{_upper(bad if e == BAD_EDGE else GOOD)}")
    return "\n".join(lines) + "\n"


@pytest.fixture
def files(tmp_path):
    """``(bad, good)``: the graph with the indefinite edge, and the same graph with that edge definite."""
    text = _graph_text()
    bad, good = tmp_path / "bad.g2o", tmp_path / "good.g2o"
    bad.write_text(text)
    good.write_text(text.replace(_upper(BAD), _upper(GOOD)))
    return bad, good


def test_the_default_refuses_the_edge_naming_its_line_and_eigenvalues(files):
    with pytest.raises(DatasetError) as raised:
        datasets3d.read_graph(files[0])
    message = str(raised.value)
    assert message.startswith(f"{files[0]}:{BAD_LINE}: information matrix is not symmetric positive definite")
    assert information.eigenvalues_text(BAD) in message and "-893766" in message
    assert "information='nearest-psd'" in message and "--information" in message  # says how to read it anyway


@pytest.mark.parametrize("mode", ["nearest-psd", "isotropic"])
def test_each_repair_loads_the_graph_and_touches_the_bad_edge_alone(files, mode):
    g = datasets3d.read_graph(files[0], information=mode)
    reference = datasets3d.read_graph(files[1])
    assert g.num_repaired == 1 and np.flatnonzero(g.repaired).tolist() == [BAD_EDGE]
    assert g.information_repair == mode and g.repair_note == f"1 edge's information repaired ({mode})"
    fixed = g.information[BAD_EDGE]
    np.testing.assert_array_equal(fixed, fixed.T)
    assert np.linalg.eigvalsh(fixed)[0] > 0
    np.linalg.cholesky(fixed)  # what the solvers need
    others = np.arange(g.num_edges) != BAD_EDGE
    np.testing.assert_array_equal(g.information[others], reference.information[others])
    for name in ("t", "R", "t_z", "R_z"):
        np.testing.assert_array_equal(getattr(g, name), getattr(reference, name))
    copy = g.with_poses(g.t, g.R)  # the starts keep the count
    assert copy.num_repaired == 1 and copy.information_repair == mode


def test_nearest_psd_clips_the_eigenvalues_at_the_floor_and_keeps_the_eigenvectors(files):
    g = datasets3d.read_graph(files[0], information="nearest-psd")
    lam, V = np.linalg.eigh(BAD)
    floor = information.FLOOR * lam[-1]
    expected = V @ np.diag(np.maximum(lam, floor)) @ V.T  # in the file's units
    np.testing.assert_allclose(g.information[BAD_EDGE] * np.outer(se3.G2O_SCALE, se3.G2O_SCALE), expected,
                               rtol=1e-9, atol=1e-9 * lam[-1])
    repaired = information.nearest_spd(BAD)
    assert np.linalg.eigvalsh(repaired)[0] == pytest.approx(floor, rel=1e-3)
    # nearer than any other matrix with the same floor tried here (Higham's theorem, spot-checked)
    for _ in range(20):
        other = repaired + 1e3 * _symmetric(RNG.normal(size=(6, 6)))
        if np.linalg.eigvalsh(other)[0] >= floor:
            assert np.linalg.norm(other - BAD) > np.linalg.norm(repaired - BAD)


def _symmetric(A):
    return 0.5 * (A + A.T)


def test_nearest_psd_of_a_definite_matrix_is_itself():
    for M in (GOOD, np.eye(3), _symmetric(RNG.normal(size=(6, 6))) + 10 * np.eye(6)):
        np.testing.assert_array_equal(information.nearest_spd(M), M)
    stacked = np.stack([GOOD, BAD])
    out = information.nearest_spd(stacked)
    np.testing.assert_array_equal(out[0], GOOD)
    assert np.linalg.eigvalsh(out[1])[0] > 0


def test_isotropic_takes_se_syncs_weights_per_block(files):
    g = datasets3d.read_graph(files[0], information="isotropic")
    tau = 3.0 / np.trace(np.linalg.inv(BAD[:3, :3]))  # SE-Sync's tau
    rotation = 3.0 / np.trace(np.linalg.inv(BAD[3:, 3:]))  # 2 kappa: the precision of its rotation noise
    expected = np.diag([tau] * 3 + [rotation / 4.0] * 3)  # ours: g2o's rotation information / 4
    np.testing.assert_allclose(g.information[BAD_EDGE], expected, rtol=1e-12)


def test_isotropic_raises_a_blocks_eigenvalues_that_are_not_positive_to_the_floor():
    M = np.diag([4.0, -1.0, 2.0])
    out = information.isotropic(M, ((0, 1), (2,)))
    floor = information.FLOOR * 4.0
    np.testing.assert_allclose(np.diag(out), [2.0 / (1 / 4.0 + 1 / floor)] * 2 + [2.0])
    assert np.linalg.eigvalsh(out)[0] > 0


def test_a_matrix_with_no_positive_eigenvalue_is_refused_by_every_mode(tmp_path):
    path = tmp_path / "hopeless.g2o"
    path.write_text(_graph_text(bad=-GOOD))
    for mode in information.MODES:
        with pytest.raises(DatasetError, match=rf"^{path}:{BAD_LINE}: .*(no positive eigenvalue|not symmetric)"):
            datasets3d.read_graph(path, information=mode)


def test_an_unknown_mode_is_refused_with_the_list(files):
    with pytest.raises(ValueError, match="nearest-psd, isotropic"):
        datasets3d.read_graph(files[0], information="clip")
    assert INFORMATION == information.MODES  # the command line's choices, written out there


@pytest.mark.parametrize("mode", ["nearest-psd", "isotropic"])
def test_the_repaired_graph_solves_and_every_row_says_so(files, mode):
    g = datasets3d.load_dataset(str(files[0]), information=mode)
    result = minimize(PoseGraph3DProblem(g), "gauss-newton")
    assert result.final_chi2 < 1e-2 * result.initial_chi2
    runs = compare.run_posegraph3d(g, methods=["gauss-newton", "lm-type3"], backends=["ours"])
    assert [r.final_chi2 for r in runs] == pytest.approx([result.final_chi2] * 2, rel=1e-6)
    note = f"1 edge's information repaired ({mode})"
    assert all(r.repaired_edges == 1 and r.note == note for r in runs)
    table = compare.format_table(runs)
    assert table.splitlines()[0].split()[-1] == "note"
    assert all(line.endswith(note) for line in table.splitlines()[2:])
    doc = json.loads(json.dumps(compare.to_json("bad", runs)))
    assert all(r["repaired_edges"] == 1 and r["information_repair"] == mode and r["note"] == note
               for r in doc["runs"])


def test_no_note_where_nothing_was_repaired(files):
    runs = compare.run_posegraph3d(datasets3d.read_graph(files[1], information="nearest-psd"),
                                   methods=["gauss-newton"], backends=["ours"])
    assert runs[0].repaired_edges == 0 and "note" not in compare.format_table(runs)
    assert "repaired_edges" not in runs[0].to_json()


def test_compare_reads_the_file_with_the_option(files, tmp_path, capsys):
    assert main(["compare", str(files[0]), "--backends", "ours", "--methods", "gauss-newton"]) == 1
    assert f"{files[0]}:{BAD_LINE}: information matrix is not symmetric positive definite" in capsys.readouterr().err
    out = tmp_path / "runs.json"
    assert main(["compare", str(files[0]), "--information", "isotropic", "--backends", "ours",
                 "--methods", "gauss-newton,dogleg", "--json", str(out)]) == 0
    table = capsys.readouterr().out
    assert "1 edge's information repaired (isotropic)" in table.splitlines()[0]  # the title
    doc = json.loads(out.read_text())
    assert [r["repaired_edges"] for r in doc["runs"]] == [1, 1]
    assert main(["compare", "curve", "--information", "isotropic"]) == 2
    assert "only pose graphs" in capsys.readouterr().err


def test_python_dash_m_course_compare_with_the_option(files):
    out = subprocess.run([sys.executable, "-m", "course", "compare", str(files[0]), "--information", "nearest-psd",
                          "--backends", "ours", "--methods", "gauss-newton"], cwd=REPO_ROOT, capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr
    row = next(line for line in out.stdout.splitlines() if line.startswith("ours"))
    assert row.endswith("1 edge's information repaired (nearest-psd)")


# ---------------------------------------------------------------- 2D, the same options

V2 = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.1\nVERTEX_SE2 2 1 1 1.6\n"
#: g2o order I11 I12 I13 I22 I23 I33: the second edge indefinite (I12 = 30 against I11 = I22 = 10)
E2 = ("EDGE_SE2 0 1 1 0 0 10 0 0 10 0 100\nEDGE_SE2 1 2 1 0 1.57 10 30 0 10 0 100\n"
      "EDGE_SE2 0 2 1 1 1.57 10 0 0 10 0 100\n")


@pytest.mark.parametrize("mode", ["nearest-psd", "isotropic"])
def test_the_2d_reader_has_the_same_options(tmp_path, mode):
    path = tmp_path / "bad2d.g2o"
    path.write_text(V2 + E2)
    with pytest.raises(DatasetError, match=rf"^{path}:5: information matrix is not symmetric positive definite "
                                           r"\(eigenvalues \[-20, 40, 100\].*information='nearest-psd'"):
        datasets2d.read_graph(path)
    g = datasets2d.load_dataset(str(path), information=mode)
    assert g.num_repaired == 1 and g.repaired.tolist() == [False, True, False]
    assert np.linalg.eigvalsh(g.information[1])[0] > 0
    np.testing.assert_array_equal(g.information[[0, 2]], np.stack([np.diag([10.0, 10.0, 100.0])] * 2))
    if mode == "isotropic":  # SE-Sync's 2D rule: tau = 2 / tr(Omega_xy^-1) (raised to the floor), kappa = I33
        floor = information.FLOOR * 100.0
        tau = 2.0 / (1 / 40.0 + 1 / floor)
        np.testing.assert_allclose(g.information[1], np.diag([tau, tau, 100.0]))
    runs = compare.run_posegraph(g, methods=["gauss-newton"], backends=["ours"])
    assert runs[0].note == f"1 edge's information repaired ({mode})" and runs[0].final_chi2 < runs[0].initial_chi2
