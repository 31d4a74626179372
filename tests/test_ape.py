"""course.problems.vio.ape and course.problems.vio.trajectory_io: readers, association, Umeyama, APE against evo
on EuRoC MH_05."""

import json

import numpy as np
import pytest

from course.app.cli import main
from course.problems.vio.ape import (
    AlignmentError,
    Similarity,
    ape,
    associate,
    euroc_mh05_files,
    statistics,
    umeyama,
)
from course.problems.vio.trajectory_io import QUATERNION_NORM_TOL, Trajectory, TrajectoryError, read_euroc_csv, read_tum

#: our APE statistics against evo's on the same files
EVO_TOL = 1e-9
KEYS = ("rmse", "mean", "median", "std", "max", "min")


def random_rotation(rng):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def trajectory(stamps, positions):
    n = len(stamps)
    quats = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return Trajectory(np.asarray(stamps, float), np.asarray(positions, float), quats)


# ---------------------------------------------------------------- against evo on MH_05


@pytest.fixture
def mh05(data_folder):
    try:
        return euroc_mh05_files(data_folder)
    except Exception as exc:  # noqa: BLE001 - the reason is the skip message
        pytest.skip(str(exc))


@pytest.mark.parametrize("align", ["se3", "sim3"])
def test_ape_equals_evo_on_mh05(mh05, align):
    pytest.importorskip("evo", reason="evo not installed here (the dev extra, Python 3.11-3.14)")
    from evo.core import metrics, sync
    from evo.tools import file_interface

    gt_path, est_path = mh05
    ref = file_interface.read_euroc_csv_trajectory(str(gt_path))
    est = file_interface.read_tum_trajectory_file(str(est_path))
    ref, est = sync.associate_trajectories(ref, est, max_diff=0.01)
    est.align(ref, correct_scale=(align == "sim3"))
    metric = metrics.APE(metrics.PoseRelation.translation_part)
    metric.process_data((ref, est))
    theirs = metric.get_all_statistics()

    ours = ape(read_euroc_csv(gt_path), read_tum(est_path), align=align)
    stats = ours.stats
    assert stats["pairs"] == len(metric.error) == 1078
    # the same pairs: the associated stamps are evo's
    assert np.array_equal(read_euroc_csv(gt_path).timestamps[ours.ref_indices], ref.timestamps)
    assert np.array_equal(read_tum(est_path).timestamps[ours.est_indices], est.timestamps)
    np.testing.assert_allclose(ours.errors, metric.error, rtol=0, atol=EVO_TOL)
    for key in KEYS:
        assert abs(stats[key] - float(theirs[key])) <= EVO_TOL, key


def test_mh05_matches_the_references_figures(mh05):
    """REFERENCES.md: evo 1.38.1 ``evo_ape euroc GT EST -a`` printed these (6 decimals)."""
    stats = ape(read_euroc_csv(mh05[0]), read_tum(mh05[1]), align="se3").stats
    printed = {"rmse": 0.245723, "mean": 0.231451, "median": 0.244383, "std": 0.082523, "max": 0.449682,
               "min": 0.033621}
    for key, value in printed.items():
        assert abs(stats[key] - value) <= 5e-7, key


def test_cli_euroc_mh05(mh05, tmp_path, capsys):
    path = tmp_path / "ape.json"
    assert main(["ape", "euroc-mh05", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    assert "source's LM run" in out and "0.245723" in out and "0.247000" in out
    doc = json.loads(path.read_text())
    assert set(doc) == {"rmse", "median", "mean", "std", "max", "min", "pairs"}
    assert doc["pairs"] == 1078


# ---------------------------------------------------------------- synthetic


@pytest.mark.parametrize("with_scale", [False, True])
def test_a_known_similarity_aligns_back(with_scale):
    rng = np.random.default_rng(3)
    truth = np.cumsum(rng.normal(size=(200, 3)), axis=0)
    R, t, scale = random_rotation(rng), rng.normal(size=3) * 10, (2.5 if with_scale else 1.0)
    # the estimate is the truth in another frame: truth = scale R est + t
    est = ((truth - t) @ R) / scale
    stamps = np.arange(200) * 0.1
    result = ape(trajectory(stamps, truth), trajectory(stamps + 0.003, est), align="sim3" if with_scale else "se3")
    assert result.stats["pairs"] == 200
    assert result.stats["max"] < 1e-9
    np.testing.assert_allclose(result.alignment.R, R, atol=1e-10)
    np.testing.assert_allclose(result.alignment.t, t, atol=1e-9)
    assert result.alignment.scale == pytest.approx(scale, rel=1e-12)


def test_sim3_recovers_a_scale_se3_cannot():
    rng = np.random.default_rng(4)
    truth = rng.normal(size=(50, 3)) * 5
    stamps = np.arange(50.0)
    est = trajectory(stamps, 0.5 * truth)
    assert ape(trajectory(stamps, truth), est, align="sim3").stats["rmse"] < 1e-12
    assert ape(trajectory(stamps, truth), est, align="se3").stats["rmse"] > 1.0


def test_umeyama_never_returns_a_reflection():
    rng = np.random.default_rng(5)
    x = rng.normal(size=(30, 3))
    mirrored = x * np.array([1.0, 1.0, -1.0])
    fit = umeyama(x, mirrored)
    assert np.linalg.det(fit.R) == pytest.approx(1.0, abs=1e-12)


def test_umeyama_refuses_collinear_points():
    line = np.outer(np.arange(10.0), [1.0, 2.0, 3.0])
    with pytest.raises(AlignmentError, match="degenerate"):
        umeyama(line, line + 1.0)


def test_statistics():
    stats = statistics([3.0, 4.0])
    assert stats == {"rmse": pytest.approx(np.sqrt(12.5)), "median": 3.5, "mean": 3.5, "std": 0.5, "max": 4.0,
                     "min": 3.0, "pairs": 2}
    assert Similarity.identity().apply([[1.0, 2.0, 3.0]]).tolist() == [[1.0, 2.0, 3.0]]


# ---------------------------------------------------------------- association


def test_association_nearest_within_max_diff_earlier_on_a_tie():
    ref = np.array([0.0, 0.02, 0.04, 0.06, 1.0])
    est = np.array([0.01, 0.031, 0.5, 1.0099, 1.02])
    i_ref, i_est = associate(ref, est, max_diff=0.01)
    # 0.01 is equally near 0.0 and 0.02 (to rounding: 0.02 - 0.01 == 0.01 - 0.0): the earlier;
    # 0.031 -> 0.04 (0.009 < 0.011); 0.5 none; 1.0099 -> 1.0; 1.02 is 0.02 away: none
    assert i_est.tolist() == [0, 1, 3]
    assert i_ref.tolist() == [0, 2, 4]


def test_association_walks_the_shorter_trajectory():
    long_ = np.arange(0.0, 1.0, 0.005)  # 200 Hz
    short = np.array([0.1001, 0.5003])
    i_ref, i_est = associate(short, long_)  # here the reference is the shorter one
    assert i_ref.tolist() == [0, 1]
    assert long_[i_est].tolist() == pytest.approx([0.1, 0.5])
    i_ref, i_est = associate(long_, short)
    assert i_est.tolist() == [0, 1] and long_[i_ref].tolist() == pytest.approx([0.1, 0.5])


def test_no_pairs_is_an_error():
    a = trajectory([0.0, 1.0, 2.0], np.eye(3))
    b = trajectory([10.0, 11.0, 12.0], np.eye(3))
    with pytest.raises(AlignmentError, match="within 0.01 s"):
        ape(a, b)


# ---------------------------------------------------------------- readers


TUM = "# t x y z qx qy qz qw\n1.0 0 0 0 0 0 0 1\n\n2.0 1 2 3 0 0 0.7071068 0.7071068\n"
EUROC = ("#timestamp [ns], p.x, p.y, p.z, q.w, q.x, q.y, q.z, v.x\n"
         "1403638519492829440,4.46,-1.68,0.58,0.238261,-0.757610,-0.348629,-0.497711,0.1\n"
         "1403638519497829376,4.47,-1.68,0.58,0.238261,-0.757616,-0.348621,-0.497709,0.1\n")


def write(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_read_tum(tmp_path):
    traj = read_tum(write(tmp_path, "a.txt", TUM))
    assert traj.timestamps.tolist() == [1.0, 2.0]
    assert traj.positions[1].tolist() == [1.0, 2.0, 3.0]
    np.testing.assert_allclose(np.linalg.norm(traj.quaternions, axis=1), 1.0, atol=1e-15)
    assert traj.quaternions[0].tolist() == [1.0, 0.0, 0.0, 0.0]  # (w, x, y, z)
    np.testing.assert_allclose(traj.rotations()[1], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-6)


def test_read_euroc(tmp_path):
    traj = read_euroc_csv(write(tmp_path, "gt.csv", EUROC))
    assert traj.timestamps[0] == float(1403638519492829440) / 1e9
    assert traj.positions[:, 0].tolist() == [4.46, 4.47]
    assert traj.quaternions[0, 0] == pytest.approx(0.238261, abs=1e-5)


@pytest.mark.parametrize("text, where, what", [
    ("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 1\n", ":2:", "7 fields, expected 8"),
    ("1.0 0 0 0 0 0 0 1\n2.0 0 zero 0 0 0 0 1\n", ":2:", "field y: 'zero' is not a number"),
    ("1.0 0 0 0 0 0 0 1\n2.0 0 0 nan 0 0 0 1\n", ":2:", "field z: 'nan' is not a finite number"),
    ("1.0 0 0 0 0 0 0 1\n\n1.0 0 0 0 0 0 0 1\n", ":3:", "does not increase on line 1"),
    ("1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1.01\n", ":2:", "norm 1.01 differs from 1"),
    ("# only a comment\n", "", "no poses"),
])
def test_tum_errors_name_file_line_and_field(tmp_path, text, where, what):
    path = write(tmp_path, "bad.txt", text)
    with pytest.raises(TrajectoryError) as info:
        read_tum(path)
    message = str(info.value)
    assert message.startswith(str(path)) and where in message and what in message, message


@pytest.mark.parametrize("text, where, what", [
    (EUROC + "1403638519502829312,4.47,-1.68,0.58,0.238261,-0.757616,-0.348621\n", ":4:", "7 columns, expected 9"),
    ("1,2,3,4,5,6,7\n", ":1:", "expected at least 8"),
    (EUROC + "1403638519502.5,4.47,-1.68,0.58,0.238261,-0.757616,-0.348621,-0.497709,0.1\n", ":4:",
     "not an integer number of nanoseconds"),
    (EUROC + "1403638519502829312,4.47,-1.68,x,0.238261,-0.757616,-0.348621,-0.497709,0.1\n", ":4:",
     "field p.z: 'x' is not a number"),
    (EUROC + "1403638519497829376,4.47,-1.68,0.58,0.238261,-0.757616,-0.348621,-0.497709,0.1\n", ":4:",
     "does not increase on line 3"),
])
def test_euroc_errors_name_file_line_and_field(tmp_path, text, where, what):
    path = write(tmp_path, "bad.csv", text)
    with pytest.raises(TrajectoryError) as info:
        read_euroc_csv(path)
    message = str(info.value)
    assert message.startswith(str(path)) and where in message and what in message, message


def test_quaternion_tolerance_is_explicit(tmp_path):
    ok = 1.0 + QUATERNION_NORM_TOL / 2
    traj = read_tum(write(tmp_path, "ok.txt", f"1.0 0 0 0 0 0 0 {ok!r}\n"))
    assert traj.quaternions[0].tolist() == [1.0, 0.0, 0.0, 0.0]


def test_cli_files_and_usage_errors(tmp_path, capsys):
    gt = write(tmp_path, "gt.txt", "".join(f"{k}.0 {k} {k * k % 7} {k % 3} 0 0 0 1\n" for k in range(10)))
    path = tmp_path / "out.json"
    assert main(["ape", str(gt), str(gt), "--align", "sim3", "--json", str(path)]) == 0
    doc = json.loads(path.read_text())
    assert doc["pairs"] == 10 and doc["max"] < 1e-9
    assert main(["ape", str(gt)]) == 2
    assert main(["ape", str(gt), str(tmp_path / "missing.txt")]) == 1
    assert "missing.txt: no such file" in capsys.readouterr().err
