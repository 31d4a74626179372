"""``benchmark --suite`` (course.app.benchmark_suite) and the machine beside its ratios (course.app.machine):
the description's fields, the JSON of a one-row run, ``--only``, ``--compare`` on hand-written files, a peer
missing or a TODO as a row, and the measured page's commands. No timing is judged: the machine is shared."""

import json
import os
import platform
import re
import shlex
import subprocess
import sys
from datetime import datetime, timedelta

import numpy as np
import pytest
from conftest import needs

from course.app import benchmark_suite, machine
from course.app.cli import main as course_main
from course.core import peers
from course.core.impl import REPO_ROOT

ROW_KEYS = {"name", "divides", "ratio", "min", "max", "ours_seconds", "peer_seconds", "repeats", "ratios", "goal",
            "met", "status", "reason"}


def hide(monkeypatch, *libraries):
    """``import`` of each library fails here, as on a machine without its wheel."""
    for name in libraries:
        monkeypatch.setitem(sys.modules, name, None)
    monkeypatch.setattr(peers, "_announced", set())


# ------------------------------------------------------------------ the machine


def test_the_machine_description_has_every_field():
    described = machine.describe("python -m course benchmark --suite")
    assert described["command"] == "python -m course benchmark --suite"
    assert isinstance(described["cpu"], str) and described["cpu"]
    assert described["cores"] == os.cpu_count()
    assert described["affinity"] is None or 1 <= described["affinity"] <= described["cores"]
    blas = [entry for entry in described["blas"] if entry["user_api"] == "blas"]
    assert blas, described["blas"]
    for entry in blas:
        assert set(machine.BLAS_FIELDS) | {"folder"} <= set(entry)
        assert entry["internal_api"] and entry["version"] and entry["num_threads"] >= 1
    assert platform.python_version() in described["python"]
    assert described["versions"]["numpy"] == np.__version__
    import scipy

    assert described["versions"]["scipy"] == scipy.__version__
    assert {"gtsam", "g2opy", "pycolmap", "pyceres", "jax"} <= set(described["versions"])
    for name in ("gtsam", "g2opy", "pycolmap", "pyceres", "jax"):
        assert (described["versions"][name] is not None) == peers.installed(name), name
    when = datetime.fromisoformat(described["date"])
    assert when.utcoffset() == timedelta(0)
    assert described["commit"] is None or re.fullmatch(r"[0-9a-f]{40}", described["commit"])
    json.dumps(described)  # JSON as it is


def test_the_cpu_model_comes_from_cpuinfo_and_falls_back_without_it(tmp_path, monkeypatch):
    cpuinfo = tmp_path / "cpuinfo"
    cpuinfo.write_text("processor\t: 0\nvendor_id\t: GenuineIntel\nmodel name\t: Example CPU @ 2.10GHz\n"
                       "flags\t\t: fpu sse4_2 avx avx2 fma\n")
    monkeypatch.setattr(machine, "CPUINFO", str(cpuinfo))
    assert machine.cpu_model() == "Example CPU @ 2.10GHz"
    assert machine.simd() == ["sse4_2", "avx", "avx2", "fma"]
    monkeypatch.setattr(machine, "CPUINFO", str(tmp_path / "absent"))
    assert machine.cpu_model() == (platform.processor() or platform.machine() or "unknown")
    assert machine.simd() is None


def described(cpu="CPU A", kernel="Haswell", gtsam="4.2", blas_version="0.3.27"):
    return {"cpu": cpu, "simd": ["avx2"], "cores": 2, "affinity": 2, "python": "CPython 3.11.7", "platform": "Linux",
            "blas": [{"user_api": "blas", "internal_api": "openblas", "prefix": "libscipy_openblas",
                      "version": blas_version, "threading_layer": "pthreads", "architecture": kernel,
                      "num_threads": 1, "folder": "numpy.libs"}],
            "versions": {"numpy": "2.4.6", "scipy": "1.17.1", "gtsam": gtsam, "g2opy": "2.3.0"},
            "date": "2026-11-27T02:20:00+00:00", "commit": "a" * 40, "dirty": False, "command": "x"}


def test_the_differences_name_cpu_kernel_and_versions_and_nothing_else():
    old, new = described(), described(cpu="CPU B", kernel="SkylakeX", gtsam="4.3")
    new["date"], new["commit"] = "2026-11-28T10:00:00+00:00", "b" * 40
    assert machine.differences(old, new) == ["CPU: CPU A -> CPU B",
                                             "BLAS openblas in numpy.libs kernel: Haswell -> SkylakeX",
                                             "gtsam: 4.2 -> 4.3"]
    assert machine.differences(old, described()) == []
    new = described()
    new["blas"][0]["folder"], new["versions"]["g2opy"] = "scipy.libs", None
    assert machine.differences(old, new) == ["BLAS openblas in numpy.libs: only in the old run",
                                             "BLAS openblas in scipy.libs: only in the new run (version 0.3.27, kernel "
                                             "Haswell)", "g2opy: 2.3.0 -> not installed"]


# ------------------------------------------------------------------ the rows


def test_a_row_is_the_median_of_its_repeats_ratios_with_their_spread():
    row = benchmark_suite.measured("x ours/peer", "ours / peer", [2.0, 3.0, 9.0], [1.0, 2.0, 3.0], goal=1.5)
    assert row.ratios == [2.0, 1.5, 3.0]
    assert (row.ratio, row.low, row.high) == (2.0, 1.5, 3.0)
    assert (row.ours_seconds, row.peer_seconds) == (3.0, 2.0)
    assert row.met is False
    assert set(row.as_json()) == ROW_KEYS and row.as_json()["repeats"] == 3
    assert benchmark_suite.measured("y", "", [1.0], [1.0], goal=1.0).met is True  # at the goal is met
    assert benchmark_suite.measured("z", "", [1.0], [2.0]).met is None


def test_a_failed_solve_is_a_row_and_the_rest_runs():
    from course.core.errors import SingularSystemError

    def singular(repeats, impl):
        raise SingularSystemError("the system is singular at iteration 3")

    def fine(repeats, impl):
        return {"ours/peer": ([1.0] * repeats, [2.0] * repeats)}

    chosen = [benchmark_suite.Item(name, {"ours/peer": ""}, measure)
              for name, measure in (("a", singular), ("b", fine))]
    result = benchmark_suite.run(repeats=2, out=lambda line: None, chosen=chosen, command="test")
    rows = result["rows"]
    assert result["note"] == ""  # no --note
    assert rows[0]["reason"] == "failed: SingularSystemError: the system is singular at iteration 3"
    assert rows[1]["ratio"] == 0.5 and rows[1]["repeats"] == 2


def test_the_warmup_repeats_are_dropped():
    calls = []

    def measure(repeats, impl):
        calls.append(repeats)
        return {"ours/peer": ([100.0] + [1.0] * (repeats - 1), [1.0] * repeats)}

    item = benchmark_suite.Item("x", {"ours/peer": "ours / peer"}, measure, max_repeats=3)
    (row,) = item.rows(5, "solutions", warmup=1)
    assert calls == [4] and row.ratios == [1.0, 1.0, 1.0]


def test_only_selects_an_item_a_part_of_its_name_or_a_dataset():
    items = benchmark_suite.items()
    names = [item.name for item in items]
    assert {"bal:ladybug-49", "vio:vio-sim:12:0", "2d:iteration:w10000", "2d:solution:intel", "3d:iteration:torus3D",
            "3d:solution:parking-garage", "autodiff:sphere2500"} <= set(names)

    def chosen(*only):
        return [item.name for item in benchmark_suite.select(items, only)]

    assert chosen() == names
    assert chosen("2d:solution:intel") == ["2d:solution:intel"]
    assert chosen("intel") == ["2d:solution:intel", "autodiff:intel"]  # not intel-g2o
    assert chosen("vio") == ["vio:vio-sim:12:0"] == chosen("vio-sim:12:0")
    assert set(chosen("2d")) == {n for n in names if n.startswith("2d:")}
    assert chosen("3d:solution", "bal") == ["bal:ladybug-49", "3d:solution:sphere2500", "3d:solution:torus3D",
                                            "3d:solution:parking-garage"]
    with pytest.raises(ValueError, match=r"--only '2d:sol' selects no row; the items are: bal:ladybug-49, "):
        benchmark_suite.select(items, ["2d:sol"])


def test_an_unknown_row_or_a_lone_old_file_is_a_usage_error(capsys, tmp_path):
    assert course_main(["benchmark", "--suite", "--only", "nothing"]) == 2
    assert "--only 'nothing' selects no row" in capsys.readouterr().err
    for argv in (["--json", "x.json"], ["--note", "busy"], ["--compare", "a.json"], ["--suite", "--compare", "a", "b"],
                 ["--suite", "--repeats", "0"]):
        with pytest.raises(SystemExit) as stopped:
            course_main(["benchmark", *argv])
        assert stopped.value.code == 2, argv


@needs("g2opy")
def test_the_suite_on_intel_writes_the_rows_beside_the_machine(tmp_path, data_folder, capsys):
    path = tmp_path / "suite.json"
    assert course_main(["benchmark", "--suite", "--only", "2d:solution:intel", "--repeats", "1",
                        "--note", "measured on a shared machine", "--json", str(path)]) == 0
    out = capsys.readouterr().out
    data = json.loads(path.read_text())
    assert data["note"] == "measured on a shared machine" and "--note" in data["machine"]["command"]
    assert data["format"] == benchmark_suite.FORMAT and data["repeats"] == 1 and data["impl"] == "solutions"
    assert data["warmup"] == benchmark_suite.WARMUP and data["seconds"] > 0
    assert {"cpu", "cores", "affinity", "blas", "python", "versions", "date", "commit",
            "command"} <= set(data["machine"])
    assert "--only 2d:solution:intel" in data["machine"]["command"]
    (row,) = data["rows"]
    assert set(row) == ROW_KEYS
    assert row["name"] == "2d:solution:intel ours/g2o" and row["status"] == "measured", row
    assert row["repeats"] == 1 and row["ratio"] == row["min"] == row["max"] == row["ratios"][0]
    assert row["ratio"] == pytest.approx(row["ours_seconds"] / row["peer_seconds"], rel=1e-12)
    assert row["goal"] == 1.5 and row["met"] == (row["ratio"] <= 1.5)
    assert "chordal start" in row["divides"] and "g2o" in row["divides"]
    assert "2d:solution:intel ours/g2o" in out and f"wrote {path}" in out


SMALL = {"bal": (), "vio": (), "iteration_2d": (), "solution_2d": ("manhattan:30",), "iteration_3d": ("tinyGrid3D",),
         "solution_3d": (), "autodiff": ()}


def test_a_missing_peer_is_a_row_saying_so(monkeypatch, data_folder):
    hide(monkeypatch, "g2opy", "gtsam")
    lines: list = []
    result = benchmark_suite.run(repeats=1, only=["2d", "3d"], out=lines.append,
                                 chosen=benchmark_suite.items(**SMALL), command="test")
    rows = {row["name"]: row for row in result["rows"]}
    assert rows["2d:solution:manhattan:30 ours/g2o"]["status"] == "not run"
    assert rows["2d:solution:manhattan:30 ours/g2o"]["reason"].startswith("g2opy is not installed here")
    for ours in benchmark_suite.OURS_3D:
        assert rows[f"3d:iteration:tinyGrid3D {ours}/gtsam"]["reason"].startswith("gtsam is not installed here")
        assert rows[f"3d:iteration:tinyGrid3D {ours}/g2o"]["reason"].startswith("g2opy is not installed here")
    assert all(row["ratio"] is None and row["met"] is None for row in rows.values())
    assert any("not run: g2opy is not installed here" in line for line in lines)
    assert result["machine"]["versions"]["g2opy"] is not None or not peers.installed("g2opy")


@needs("g2opy", "gtsam")
def test_a_peer_missing_in_part_of_an_item_leaves_the_rest_measured(monkeypatch, data_folder):
    hide(monkeypatch, "gtsam")
    monkeypatch.setattr(benchmark_suite, "WARMUP", 0)
    result = benchmark_suite.run(repeats=1, only=["3d:iteration"], out=lambda line: None,
                                 chosen=benchmark_suite.items(**SMALL), command="test")
    rows = {row["name"]: row for row in result["rows"]}
    assert rows["3d:iteration:tinyGrid3D ours/g2o"]["status"] == "measured"
    assert rows["3d:iteration:tinyGrid3D ours/gtsam"]["status"] == "not run"


def test_a_missing_dataset_is_a_row_naming_what_is_missing(monkeypatch, tmp_path):
    monkeypatch.setenv("COURSE_DATA", str(tmp_path / "absent"))
    result = benchmark_suite.run(repeats=1, out=lambda line: None, command="test",
                                 chosen=benchmark_suite.items(**{**SMALL, "solution_2d": ("intel",)}), only=["intel"])
    (row,) = result["rows"]
    assert row["status"] == "not run"
    assert row["reason"] == f"dataset 'intel': data folder {tmp_path / 'absent'} not found"  # not the whole help


@needs("g2opy")
def test_a_todo_of_the_implementation_is_a_row_naming_it():
    result = benchmark_suite.run(repeats=1, impl="exercises", only=["2d:solution"], out=lambda line: None,
                                 chosen=benchmark_suite.items(**SMALL), command="test")
    (row,) = result["rows"]
    assert row["status"] == "not run" and "TODO" in row["reason"], row


# ------------------------------------------------------------------ --compare


def suite_file(path, machine_description, rows):
    data = {"format": benchmark_suite.FORMAT, "machine": machine_description, "impl": "solutions", "repeats": 3,
            "rows": [{"name": name, "divides": "ours / peer", "ratio": ratio, "min": low, "max": high,
                      "status": "measured"} if ratio is not None else {"name": name, "status": "not run",
                                                                       "reason": "gtsam is not installed here"}
                     for name, ratio, low, high in rows]}
    path.write_text(json.dumps(data))
    return path


def test_moved_is_outside_the_old_spread_widened_by_half_both_spreads():
    old = {"ratio": 1.0, "min": 0.9, "max": 1.1}
    # s = (0.2 + 0.2) / 2 = 0.2: steady within [0.7, 1.3]
    assert benchmark_suite.moved(old, {"ratio": 1.29, "min": 1.19, "max": 1.39}) == ""
    assert benchmark_suite.moved(old, {"ratio": 1.31, "min": 1.21, "max": 1.41}) == "slower"
    assert benchmark_suite.moved(old, {"ratio": 0.69, "min": 0.59, "max": 0.79}) == "faster"
    point = {"ratio": 1.0, "min": 1.0, "max": 1.0}  # one repeat each: no noise, any change moves
    assert benchmark_suite.moved(point, {"ratio": 1.0, "min": 1.0, "max": 1.0}) == ""
    assert benchmark_suite.moved(point, {"ratio": 1.01, "min": 1.01, "max": 1.01}) == "slower"


def test_compare_prints_the_machines_differences_then_flags_the_moved_row_only(tmp_path, capsys):
    old = suite_file(tmp_path / "old.json", described(), [
        ("bal:ladybug-49 ours/ceres", 0.70, 0.69, 0.72),
        ("2d:solution:intel ours/g2o", 1.00, 0.95, 1.05),
        ("2d:solution:fr079 ours/g2o", 2.50, 2.40, 2.60),
        ("vio:vio-sim:12:0 window ours/gtsam", 0.81, 0.80, 0.83),
        ("2d:solution:mit ours/g2o", 1.0, 1.0, 1.0)])
    new_machine = described(cpu="CPU B", kernel="SkylakeX", gtsam="4.3")
    new = suite_file(tmp_path / "new.json", new_machine, [
        ("bal:ladybug-49 ours/ceres", 1.06, 1.04, 1.25),
        ("2d:solution:intel ours/g2o", 1.08, 1.00, 1.12),
        ("2d:solution:fr079 ours/g2o", 1.40, 1.35, 1.45),
        ("vio:vio-sim:12:0 window ours/gtsam", None, None, None),
        ("3d:solution:torus3D ours/g2o", 1.0, 1.0, 1.0)])
    assert course_main(["benchmark", "--compare", str(old), str(new)]) == 0
    lines = capsys.readouterr().out.splitlines()
    text = "\n".join(lines)
    for difference in ("CPU: CPU A -> CPU B", "BLAS openblas in numpy.libs kernel: Haswell -> SkylakeX",
                       "gtsam: 4.2 -> 4.3"):
        assert difference in text
    first_row = next(i for i, line in enumerate(lines) if line.startswith("bal:ladybug-49"))
    assert max(i for i, line in enumerate(lines) if "->" in line) < first_row  # the machines first

    def row(name):
        (line,) = [line for line in lines if line.startswith(name + " ")]
        return line

    assert row("bal:ladybug-49 ours/ceres").endswith("SLOWER") and "0.700 (0.690 to 0.720)" in row("bal:ladybug-49")
    assert "1.060 (1.040 to 1.250)" in row("bal:ladybug-49")
    assert row("2d:solution:intel ours/g2o").endswith(" -")
    assert row("2d:solution:fr079 ours/g2o").endswith("FASTER")
    assert row("vio:vio-sim:12:0 window ours/gtsam").endswith("not run")
    assert "only in the old run: 2d:solution:mit ours/g2o" in text
    assert "only in the new run: 3d:solution:torus3D ours/g2o" in text
    assert "moved: 2 of 4 rows in both (bal:ladybug-49 ours/ceres slower)" in text


def test_compare_on_the_same_machine_says_so(tmp_path):
    rows = [("2d:solution:intel ours/g2o", 1.0, 0.9, 1.1)]
    old = benchmark_suite.load(suite_file(tmp_path / "a.json", described(), rows))
    lines: list = []
    flags = benchmark_suite.compare(old, old, out=lines.append)
    assert flags == {"2d:solution:intel ours/g2o": ""}
    assert "the same CPU, cores, BLAS and versions" in lines


def test_a_file_that_is_not_a_suite_s_is_named_with_its_line_or_row(tmp_path):
    broken = tmp_path / "broken.json"
    broken.write_text('{"rows": [\n  {"name": "x",}\n]}')
    with pytest.raises(ValueError, match=r"broken\.json:2: "):
        benchmark_suite.load(broken)
    other = tmp_path / "other.json"
    other.write_text('{"graph": "intel"}')
    with pytest.raises(ValueError, match=r"other\.json: not a `benchmark --suite` file"):
        benchmark_suite.load(other)
    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({"machine": {}, "rows": [{"name": "a b", "status": "measured", "ratio": 1.0,
                                                           "min": 0.9}]}))
    with pytest.raises(ValueError, match=r"partial\.json: rows\[0\] \(a b\): no field 'max'"):
        benchmark_suite.load(partial)
    with pytest.raises(ValueError, match=r"absent\.json: No such file"):
        benchmark_suite.load(tmp_path / "absent.json")


# ------------------------------------------------------------------ the measured page (docs/measured.md)


def page_commands() -> list:
    """The measured page's ``benchmark --suite`` commands (its ```bash blocks)."""
    blocks = re.findall(r"```bash\n(.*?)```", (REPO_ROOT / "docs" / "measured.md").read_text(), re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if "benchmark --suite" in line]


@pytest.mark.slow
@needs("g2opy")
def test_the_measured_page_s_suite_commands_run(tmp_path, data_folder):
    commands = page_commands()
    assert len(commands) == 2 and "--json intel.json" in commands[0] and "--compare intel.json" in commands[1]
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    outputs = []
    for line in commands:
        argv = shlex.split(line)
        assert argv[:3] == ["python", "-m", "course"]
        done = subprocess.run([sys.executable, *argv[1:]], cwd=tmp_path, env=env, capture_output=True, text=True,
                              timeout=600)
        assert done.returncode == 0, f"{line}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
        outputs.append(done.stdout)
    (row,) = json.loads((tmp_path / "intel.json").read_text())["rows"]
    assert row["status"] == "measured" and row["repeats"] == 3
    assert "the same CPU, cores, BLAS and versions" in outputs[1]
    assert re.search(r"^2d:solution:intel ours/g2o .*\d\.\d{3} \(.*\) +(-|SLOWER|FASTER)$", outputs[1], re.M)
