"""Tests for course.problems.posegraph.dataset: readers, writers, named datasets, the Manhattan generator."""

import logging
import shutil

import numpy as np
import pytest

from course.app.datasets import list_other_data
from course.core.data import data_dir, gtsam_data_dir
from course.core.errors import DatasetError
from course.geometry import se2 as geometry
from course.problems.posegraph import dataset as datasets
from course.problems.posegraph.dataset import load_dataset, read_graph, write_g2o, write_toro
from course.problems.posegraph.graph import PoseGraph

ARRAYS = ("poses", "edges_i", "edges_j", "measurements", "information", "ids")

SIZES = {
    "intel": (729, 3070),
    "test_quadrat": (4, 5),
    "intel-g2o": (1228, 1483),
    "m3500": (3500, 5453),
    "mit": (808, 827),
    "csail": (1045, 1172),
    "fr079": (989, 1217),
}


def assert_same_graph(a, b, fields=ARRAYS):
    for name in fields:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def small_graph():
    """Non-contiguous ids, larger id first, non-diagonal information, two fixed poses."""
    info = np.array([[10.0, 1.0, 2.0], [1.0, 20.0, 3.0], [2.0, 3.0, 30.0]])
    return PoseGraph(
        poses=np.array([[0.0, 0.0, 0.0], [1.0 / 3.0, -0.1, 0.7], [2.0, 1e-17, -3.1]]),
        edges_i=[1, 1, 0],
        edges_j=[0, 2, 2],
        measurements=np.array([[-0.3, 0.1, -0.7], [1.5, 0.2, np.pi / 7], [-0.0, 2.0, 3.0]]),
        information=np.stack([info, 2.0 * info, np.diag([1.0, 2.0, 3.0])]),
        fixed=[0, 2],
        ids=[10, 5, 42],
    )


# --- named datasets from the shared data folder -----------------------------------------


@pytest.mark.parametrize("name", list(SIZES))
def test_named_dataset_sizes(name, data_folder):
    graph = load_dataset(name)
    assert (graph.num_poses, graph.num_edges) == SIZES[name]
    assert graph.poses.shape == (SIZES[name][0], 3)
    assert graph.information.shape == (SIZES[name][1], 3, 3)
    np.testing.assert_array_equal(graph.ids, np.arange(graph.num_poses))
    np.testing.assert_array_equal(graph.fixed, [0])
    assert graph.name == name
    assert np.isfinite(graph.chi2())


def test_intel_toro_order_direction_and_chi2(data_folder):
    graph = load_dataset("intel")
    assert 2.0e6 < graph.chi2() < 2.1e6
    # odometry edges are written larger id first; the measurement is x_i^-1 o x_j as written
    odo = graph.edges_i == graph.edges_j + 1
    assert odo.sum() == 728
    rel = geometry.between(graph.poses[graph.edges_i[odo]], graph.poses[graph.edges_j[odo]])
    np.testing.assert_allclose(rel, graph.measurements[odo], atol=1e-5)
    # TORO order I11 I12 I22 I33 I13 I23: odometry is diag(20, 20, 100)
    np.testing.assert_array_equal(graph.information[odo][0], np.diag([20.0, 20.0, 100.0]))


def test_mit_initial_chi2(data_folder):
    assert 4.3e9 < load_dataset("mit").chi2() < 4.5e9


def test_toro_pair_by_prefix_or_either_file(data_folder):
    prefix = data_folder / "test_quadrat" / "test_quadrat"
    graphs = [read_graph(prefix), read_graph(f"{prefix}-v.dat"), read_graph(f"{prefix}-e.dat")]
    for graph in graphs:
        assert_same_graph(graph, graphs[0])
        assert graph.name == "test_quadrat"
    assert load_dataset(str(prefix)).num_edges == 5


def test_round_trip_real_data(tmp_path, data_folder):
    graph = load_dataset("m3500")
    write_g2o(graph, tmp_path / "m.g2o")
    write_toro(graph, tmp_path / "m.graph")
    assert_same_graph(read_graph(tmp_path / "m.g2o"), graph)
    assert_same_graph(read_graph(tmp_path / "m.graph"), graph)


# --- gtsam wheel ------------------------------------------------------------------------


@pytest.fixture
def gtsam_data():
    folder = gtsam_data_dir()
    if folder is None or not (folder / "w100.graph").is_file():
        pytest.skip("gtsam (with its Data folder) is not installed")
    return folder


def test_gtsam_graphs(gtsam_data, caplog):
    with caplog.at_level(logging.INFO, logger="course.problems.posegraph.dataset"):
        w100 = load_dataset("w100")
        w10000 = load_dataset("w10000")
    assert (w100.num_poses, w100.num_edges) == (100, 300)
    assert (w10000.num_poses, w10000.num_edges) == (10000, 64311)
    assert "skipped 5875 EQUIV" in caplog.text
    assert np.isfinite(w10000.chi2())


# --- round trips and format details -----------------------------------------------------


@pytest.mark.parametrize("writer", [write_g2o, write_toro])
def test_round_trip_is_exact(writer, tmp_path):
    graph = small_graph()
    path = tmp_path / "g.txt"
    writer(graph, path)
    back = read_graph(path)
    assert_same_graph(back, graph)
    expected_fixed = [0, 2] if writer is write_g2o else [0]  # TORO has no FIX record
    np.testing.assert_array_equal(back.fixed, expected_fixed)


def test_write_g2o_tags_and_file_ids(tmp_path):
    write_g2o(small_graph(), tmp_path / "g.g2o")
    lines = (tmp_path / "g.g2o").read_text().splitlines()
    assert lines[0].split()[:2] == ["VERTEX_SE2", "10"]
    assert lines[3].split()[:3] == ["EDGE_SE2", "5", "10"]
    assert lines[-2:] == ["FIX 10", "FIX 42"]
    assert lines[3].split()[6:] == ["10.0", "1.0", "2.0", "20.0", "3.0", "30.0"]


def test_information_order_toro_vs_g2o(tmp_path):
    info = np.array([[10.0, 1.0, 2.0], [1.0, 20.0, 3.0], [2.0, 3.0, 30.0]])
    vertices = "VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\n"
    toro = tmp_path / "g.graph"  # I11 I12 I22 I33 I13 I23
    toro.write_text(vertices + "EDGE2 0 1 1 0 0 10 1 20 30 2 3\n")
    g2o = tmp_path / "g.g2o"  # I11 I12 I13 I22 I23 I33
    g2o.write_text(
        vertices.replace("VERTEX2", "VERTEX_SE2") + "EDGE_SE2 0 1 1 0 0 10 1 2 20 3 30\n")
    np.testing.assert_array_equal(read_graph(toro).information[0], info)
    np.testing.assert_array_equal(read_graph(g2o).information[0], info)
    write_toro(read_graph(g2o), tmp_path / "out.graph")
    assert (tmp_path / "out.graph").read_text().splitlines()[-1].split()[6:] == [
        "10.0", "1.0", "20.0", "30.0", "2.0", "3.0"]


def test_ids_fix_comments_equiv(tmp_path, caplog):
    path = tmp_path / "g.g2o"
    path.write_text(
        "# a comment\n\nVERTEX_SE2 7 0 0 0\nVERTEX_SE2 3 1 -0.000000 0\n"
        "VERTEX_SE2 9 2 0 0\nEQUIV 9 7\nEDGE_SE2 9 3 -1 0 0 1 0 0 1 0 1\nFIX 3 9\n"
    )
    with caplog.at_level(logging.INFO, logger="course.problems.posegraph.dataset"):
        graph = read_graph(path)
    np.testing.assert_array_equal(graph.ids, [7, 3, 9])
    assert (graph.edges_i[0], graph.edges_j[0]) == (2, 1)
    np.testing.assert_array_equal(graph.fixed, [1, 2])
    assert "skipped 1 EQUIV" in caplog.text


# --- malformed files --------------------------------------------------------------------

V = "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0\n"
MALFORMED = {
    "unknown tag": (V + "VERTEX_XY 2 0 0\n", 3, ["unknown tag", "VERTEX_XY"]),
    "field count": (V + "EDGE_SE2 0 1 1 0 0 1 0 0 1 0\n", 3,
                    ["EDGE_SE2", "10 values", "expected 11"]),
    "not a number": (V + "EDGE_SE2 0 1 1 0 x 1 0 0 1 0 1\n", 3, ["dtheta", "'x'"]),
    "not a number (info)": (V + "EDGE2 0 1 1 0 0 1 0 nan 1 0 0\n", 3, ["I22", "'nan'"]),
    "bad id": ("VERTEX_SE2 0.5 0 0 0\n", 1, ["field id", "integer"]),
    "missing vertex": (V + "EDGE_SE2 0 5 1 0 0 1 0 0 1 0 1\n", 3, ["missing vertex id 5"]),
    "not SPD": (V + "EDGE_SE2 0 1 1 0 0 1 0 0 -1 0 1\n", 3, ["not symmetric positive definite"]),
    "g2o order in TORO": ("VERTEX2 0 0 0 0\nVERTEX2 1 1 0 0\nEDGE2 0 1 1 0 0 1 0 0 1 0 1\n",
                          3, ["not symmetric positive definite", "I11 I12 I22 I33 I13 I23"]),
    "duplicate vertex": (V + "VERTEX_SE2 1 2 0 0\n", 3, ["duplicate vertex id 1", ":2"]),
    "FIX missing vertex": (V + "FIX 4\n", 3, ["FIX", "missing vertex id 4"]),
}


@pytest.mark.parametrize("kind", list(MALFORMED))
def test_malformed_file(kind, tmp_path):
    text, line, fragments = MALFORMED[kind]
    path = tmp_path / "bad.g2o"
    path.write_text(text)
    with pytest.raises(DatasetError) as err:
        read_graph(path)
    message = str(err.value)
    assert f"{path}:{line}:" in message
    for fragment in fragments:
        assert fragment in message


@pytest.mark.parametrize("text", ["", "# only a comment\n\n", "EQUIV 1 2\n"])
def test_empty_graph(text, tmp_path):
    path = tmp_path / "empty.graph"
    path.write_text(text)
    with pytest.raises(DatasetError, match="no vertices") as err:
        read_graph(path)
    assert str(path) in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(DatasetError, match="does not exist") as err:
        read_graph(tmp_path / "nope.g2o")
    assert str(tmp_path / "nope.g2o") in str(err.value)
    with pytest.raises(DatasetError, match="nope-e.dat"):  # half of a TORO pair
        (tmp_path / "nope-v.dat").write_text("VERTEX2 0 0 0 0\n")
        read_graph(tmp_path / "nope")


# --- Manhattan generator ----------------------------------------------------------------


def test_manhattan_deterministic_with_ground_truth():
    graph = datasets.manhattan(400, seed=3)
    assert_same_graph(graph, load_dataset("manhattan:400:3"))
    np.testing.assert_array_equal(graph.ground_truth, datasets.manhattan(400, 3).ground_truth)
    assert not np.array_equal(graph.measurements, datasets.manhattan(400, seed=4).measurements)
    assert load_dataset("manhattan:50").name == "manhattan:50:0"

    assert graph.num_poses == 400 and graph.ground_truth.shape == (400, 3)
    np.testing.assert_array_equal(graph.ground_truth[:, :2], np.round(graph.ground_truth[:, :2]))
    closures = graph.edges_j - graph.edges_i > 1
    assert closures.sum() > 50
    same_cell = graph.ground_truth[graph.edges_i[closures], :2] == graph.ground_truth[
        graph.edges_j[closures], :2]
    assert same_cell.all()
    # the truth fits the noisy measurements (chi2 about 3 per edge); the drifted start does not
    truth_chi2 = graph.chi2(graph.ground_truth)
    assert truth_chi2 < 5 * graph.num_edges
    assert graph.chi2() > 20 * truth_chi2
    # the initial estimate is the composition of the odometry
    odo = ~closures
    rel = geometry.between(graph.poses[graph.edges_i[odo]], graph.poses[graph.edges_j[odo]])
    np.testing.assert_allclose(rel, graph.measurements[odo], atol=1e-12)


def test_manhattan_bad_names():
    for name in ["manhattan:", "manhattan:x", "manhattan:10:1:2"]:
        with pytest.raises(DatasetError, match="manhattan:N"):
            load_dataset(name)
    with pytest.raises(ValueError):
        datasets.manhattan(1)


# --- names, data folder, COURSE_DATA ----------------------------------------------------


def test_unknown_name_lists_known_names():
    with pytest.raises(DatasetError) as err:
        load_dataset("nosuch")
    for name in [*SIZES, "w10000", "manhattan:N"]:
        assert name in str(err.value)


def test_course_data_override(tmp_path, monkeypatch, data_folder):
    shutil.copytree(data_folder / "test_quadrat", tmp_path / "test_quadrat")
    monkeypatch.setenv("COURSE_DATA", str(tmp_path))
    assert data_dir() == tmp_path
    graph = load_dataset("test_quadrat")
    assert graph.num_poses == 4 and str(tmp_path) in graph.source
    with pytest.raises(DatasetError, match="intel_toro/intel") as err:
        load_dataset("intel")
    assert str(tmp_path) in str(err.value)
    available = {info.name: info for info in datasets.list_datasets()}
    assert available["test_quadrat"].available
    assert not available["intel"].available and "not found" in available["intel"].reason


def test_missing_data_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("COURSE_DATA", str(tmp_path / "absent"))
    with pytest.raises(DatasetError, match="COURSE_DATA") as err:
        load_dataset("m3500")
    assert str(tmp_path / "absent") in str(err.value)
    # how to get it, and what works without it
    assert "your instructor ships it" in str(err.value) and "`python -m course demo`" in str(err.value)
    info = {i.name: i for i in datasets.list_datasets()}["m3500"]
    assert (info.poses, info.edges, info.available) == (3500, 5453, False)
    assert "data folder" in info.reason and "not found" in info.reason  # the listing's row: short


def test_the_other_chapters_data_are_listed_and_missing_ones_say_why(tmp_path, monkeypatch):
    rows = {name: (size, where, reason) for name, size, where, reason in list_other_data()}
    assert {"ladybug-49", "dubrovnik-3-7", "bal-synthetic:C:P[:seed]", "euroc-mh05",
            "vio-sim[:seconds[:seed]]"} <= set(rows)
    assert rows["ladybug-49"][0] == "49 cameras, 7776 points, 31843 obs"
    monkeypatch.setenv("COURSE_DATA", str(tmp_path / "absent"))
    rows = {name: reason for name, _, _, reason in list_other_data()}
    assert "not found" in rows["ladybug-49"] and "missing" in rows["euroc-mh05"]
    with pytest.raises(DatasetError, match="COURSE_DATA"):
        from course.problems.vio import ape

        ape.euroc_mh05_files()
    assert rows["vio-sim[:seconds[:seed]]"] == ""
