"""course.release.platforms: the markers per target, the README's requirements table, and (slow) the index."""

import dataclasses
import os
import socket
import subprocess
import time
from pathlib import Path
from urllib.parse import urlparse

import pytest
from packaging.utils import canonicalize_name

from course.release import platforms
from course.release.platforms import (
    TARGETS,
    ResolutionError,
    applicable,
    requirements,
    requirements_table,
    resolve,
    target,
)

ROOT = Path(__file__).resolve().parent.parent
STUDENT_README = ROOT / "course" / "release" / "student_tree" / "README.md"


def names(requirement_strings):
    return [text.split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip() for text in requirement_strings]


def test_targets_are_every_python_on_every_platform():
    assert len(TARGETS) == 24
    assert len({(one.python, one.platform) for one in TARGETS}) == 24
    assert {one.python for one in TARGETS} == {"3.10", "3.11", "3.12", "3.13", "3.14", "3.15"}
    assert {one.platform for one in TARGETS} == {"linux-x86_64", "linux-aarch64", "macos-arm64", "windows-amd64"}


def test_linux_targets_name_every_manylinux_tag_from_2_28_down():
    tags = target("3.12", "linux-aarch64").tags
    assert tags[0] == "manylinux_2_28_aarch64"
    assert {f"manylinux_2_{minor}_aarch64" for minor in range(17, 29)} <= set(tags)
    assert "manylinux2014_aarch64" in tags
    assert target("3.12", "macos-arm64").tags == ("macosx_14_0_arm64",)
    assert target("3.12", "windows-amd64").tags == ("win_amd64",)


def test_the_marker_environment_is_the_targets():
    mac = target("3.12", "macos-arm64").environment
    assert (mac["sys_platform"], mac["platform_system"], mac["platform_machine"]) == ("darwin", "Darwin", "arm64")
    assert mac["platform_release"] == "23.0.0"  # macOS 14
    windows = target("3.15", "windows-amd64").environment
    assert (windows["os_name"], windows["platform_machine"], windows["python_full_version"]) == (
        "nt",
        "AMD64",
        "3.15.0",
    )


def test_qdldl_and_jupytext_are_left_out_on_3_15_only():
    core = requirements()
    for one in TARGETS:
        got = names(applicable(core, one))
        assert ("qdldl" in got) == (one.python != "3.15"), one
        assert ("jupytext" in got) == (one.python != "3.15"), one
        assert {"numpy", "scipy", "matplotlib"} <= set(got)


def test_the_peers_markers():
    peers = requirements("peers")
    assert names(applicable(peers, target("3.12", "linux-x86_64"))) == ["pyceres", "g2opy", "gtsam", "pycolmap"]
    for python in ("3.10", "3.11", "3.12", "3.13", "3.14", "3.15"):
        assert "gtsam" not in names(applicable(peers, target(python, "windows-amd64")))
        assert "pyceres" not in names(applicable(peers, target(python, "linux-aarch64")))
        assert "pycolmap" not in names(applicable(peers, target(python, "linux-aarch64")))  # no aarch64 wheel
    for platform in ("linux-x86_64", "macos-arm64", "windows-amd64"):  # pycolmap 4.2.1: cp310-cp314 wheels
        assert "pycolmap" in names(applicable(peers, target("3.10", platform)))
        assert "pycolmap" not in names(applicable(peers, target("3.15", platform)))
    for platform in ("linux-x86_64", "linux-aarch64", "macos-arm64", "windows-amd64"):
        assert "gtsam" not in names(applicable(peers, target("3.10", platform)))
        assert "g2opy" not in names(applicable(peers, target("3.10", platform)))
    assert names(applicable(peers, target("3.15", "macos-arm64"))) == ["g2opy"]


def test_pyceres_needs_macos_14():
    peers = requirements("peers")
    macos_14 = target("3.12", "macos-arm64")
    macos_13 = dataclasses.replace(macos_14, environment={**macos_14.environment, "platform_release": "22.6.0"})
    assert "pyceres" in names(applicable(peers, macos_14))
    assert "pyceres" not in names(applicable(peers, macos_13))


def test_applicable_drops_the_markers_and_keeps_the_extras():
    windows, linux = target("3.12", "windows-amd64"), target("3.12", "linux-x86_64")
    wanted = ["foo[b,a]>=1,<2; sys_platform == 'win32'", "bar", "baz==1.0; python_version < '3.12'"]
    assert applicable(wanted, windows) == ["foo[a,b]<2,>=1", "bar"]
    assert applicable(wanted, linux) == ["bar"]


def test_requirements_table_from_a_pyproject(tmp_path):
    pyproject = tmp_path / "pyproject.toml"
    pyproject.write_text(
        "[project]\n"
        "dependencies = ['numpy', \"tiny; python_version < '3.15'\"]\n"
        "[project.optional-dependencies]\n"
        "peers = [\"alpha; sys_platform != 'win32'\", \"beta; python_version >= '3.11'\"]\n"
    )
    chosen = [target(python, platform) for platform in ("linux-x86_64", "windows-amd64") for python in ("3.10", "3.15")]
    assert requirements_table(chosen, pyproject=pyproject) == (
        "| platform | Python 3.10 | Python 3.15 |\n"
        "|---|---|---|\n"
        "| Linux x86_64 (glibc 2.28+) | alpha | all peers; no tiny |\n"
        "| Windows amd64 | no peers | beta; no tiny |\n"
    )


def test_requirements_table_is_the_markers_and_deterministic():
    table = requirements_table()
    assert table == requirements_table()
    lines = table.splitlines()
    assert len(lines) == 2 + 4
    assert lines[0].startswith("| platform | Python 3.10 |") and lines[0].endswith("| Python 3.15 |")
    row = {line.split(" | ")[0].lstrip("| "): line.strip("| ").split(" | ")[1:] for line in lines[2:]}
    assert row["Linux x86_64 (glibc 2.28+)"][2] == "all peers"
    assert row["Windows amd64"][5] == "g2opy; no qdldl, jupytext"


def test_the_student_readme_carries_the_requirements_table():
    table = requirements_table()
    assert table in STUDENT_README.read_text(encoding="utf-8"), (
        f"{STUDENT_README.relative_to(ROOT)} does not carry the current requirements table: paste the output of "
        '`python -m course.release.platforms --table` into its "Requirements" section (the table is built from the '
        "markers of pyproject.toml)"
    )


def test_main_prints_the_table(capsys):
    assert platforms.main(["--table"]) == 0
    assert capsys.readouterr().out == requirements_table()


def test_resolve_reports_pips_complaint(monkeypatch):
    stderr = (
        "WARNING: Location 'file:///somewhere/qdldl/' is ignored: it is neither a file nor a directory.\n"
        "ERROR: Could not find a version that satisfies the requirement qdldl>=0.1.9 (from versions: none)\n"
        "ERROR: No matching distribution found for qdldl>=0.1.9\n"
    )
    commands = []

    def fake_run(command, **options):
        commands.append(command)
        return subprocess.CompletedProcess(command, 1, stdout="", stderr=stderr)

    monkeypatch.setattr(platforms.subprocess, "run", fake_run)
    with pytest.raises(ResolutionError) as raised:
        resolve(["qdldl>=0.1.9"], target("3.15", "linux-aarch64"))
    message = str(raised.value)
    assert "Python 3.15 on linux-aarch64" in message
    assert "No matching distribution found for qdldl>=0.1.9" in message
    assert "WARNING: Location" not in message
    (command,) = commands
    assert command[command.index("--python-version") + 1] == "3.15"
    assert "--platform=manylinux_2_28_aarch64" in command and "--only-binary=:all:" in command
    assert "--dry-run" in command and command[-1] == "qdldl>=0.1.9"


def test_resolve_of_nothing_runs_no_pip(monkeypatch):
    monkeypatch.setattr(platforms.subprocess, "run", lambda *args, **options: pytest.fail("ran pip"))
    assert resolve([], target("3.12", "linux-x86_64")) == {}


def test_resolve_adds_the_dependencies_pip_judged_by_its_own_interpreter(monkeypatch):
    # pip leaves colorama out of tqdm's dependencies when it runs on Linux; the Windows target needs it
    tqdm = {
        "metadata": {
            "name": "tqdm",
            "version": "4.67.1",
            "requires_dist": ["colorama; platform_system == 'Windows'", "pytest; extra == 'dev'"],
        }
    }
    colorama = {"metadata": {"name": "colorama", "version": "0.4.6"}}
    asked = []

    def fake_report(wanted, one, timeout, deps):
        asked.append(list(wanted))
        return [tqdm, colorama] if "colorama" in wanted else [tqdm]

    monkeypatch.setattr(platforms, "_pip_report", fake_report)
    assert resolve(["tqdm"], target("3.12", "windows-amd64")) == {"tqdm": "4.67.1", "colorama": "0.4.6"}
    assert asked == [["tqdm"], ["tqdm", "colorama"]]
    asked.clear()
    assert resolve(["tqdm"], target("3.12", "linux-x86_64")) == {"tqdm": "4.67.1"}
    assert asked == [["tqdm"]]


def _unreachable_index() -> str | None:
    """Why the package index cannot be reached (one connection, 5 s at most), or None when it can."""
    host = urlparse(os.environ.get("PIP_INDEX_URL", "https://pypi.org/simple")).hostname or "pypi.org"
    try:
        socket.create_connection((host, 443), timeout=5).close()
    except OSError as error:
        return f"the package index ({host}:443) is unreachable ({error}): cannot resolve the targets' wheels"
    return None


@pytest.mark.slow
def test_every_target_resolves_on_the_index():
    reason = _unreachable_index()
    if reason is not None:
        pytest.skip(reason)
    start = time.monotonic()
    results = platforms.check()
    failures = [
        f"{result.target} ({what}): {error}"
        for result in results
        for what, error in (("core", result.core_error), ("peers", result.peers_error))
        if error is not None
    ]
    assert not failures, f"{len(failures)} resolutions failed:\n\n" + "\n\n".join(failures)
    assert len(results) == len(TARGETS)
    for result in results:
        assert result.core is not None and {"numpy", "scipy"} <= set(result.core), result.target
        admitted = {canonicalize_name(name) for name in result.peer_names}
        assert result.peers is not None and admitted <= set(result.peers), result.target
    print(f"{len(results)} targets resolved in {time.monotonic() - start:.0f} s")
