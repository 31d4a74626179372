"""autograder.release.platforms: the markers per target, the README's requirements table, and (slow) the index."""

import dataclasses
import os
import socket
import subprocess
import time
from pathlib import Path
from urllib.parse import urlparse

import pytest
from packaging.utils import canonicalize_name

from autograder.release import platforms
from autograder.release.platforms import (
    TARGETS,
    ResolutionError,
    applicable,
    requirements,
    requirements_table,
    resolve,
    target,
)

ROOT = Path(__file__).resolve().parent.parent
STUDENT_README = ROOT / "autograder" / "release" / "student_tree" / "README.md"


def names(requirement_strings):
    return [text.split("[")[0].split(">")[0].split("=")[0].split("<")[0].strip() for text in requirement_strings]


def test_targets_are_every_python_on_every_platform():
    assert len(TARGETS) == 24
    assert len({(one.python, one.platform) for one in TARGETS}) == 24
    assert {one.python for one in TARGETS} == {"3.10", "3.11", "3.12", "3.13", "3.14", "3.15"}
    assert {one.platform for one in TARGETS} == {"linux-x86_64", "linux-aarch64", "macos-arm64", "windows-amd64"}


def test_each_platform_has_the_resolvers_name():
    assert target("3.12", "linux-aarch64").resolver_platform == "aarch64-manylinux_2_28"
    assert target("3.12", "linux-x86_64").resolver_platform == "x86_64-manylinux_2_28"
    assert target("3.12", "macos-arm64").resolver_platform == "aarch64-apple-darwin"
    assert target("3.12", "windows-amd64").resolver_platform == "x86_64-pc-windows-msvc"
    assert platforms.MACOS_DEPLOYMENT_TARGET == "14.0"  # the label's "macOS 14+"


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


def test_qdldl_numba_and_jupytext_are_left_out_on_3_15_only():
    core = requirements()
    for one in TARGETS:
        got = names(applicable(core, one))
        assert ("qdldl" in got) == (one.python != "3.15"), one
        assert ("numba" in got) == (one.python != "3.15"), one
        assert ("jupytext" in got) == (one.python != "3.15"), one
        assert {"numpy", "scipy", "matplotlib"} <= set(got)


def test_the_peers_markers():
    peers = requirements("peers")
    assert names(applicable(peers, target("3.12", "linux-x86_64"))) == [
        "pyceres", "g2opy", "gtsam", "jax", "pycolmap", "cvxopt"]
    for platform in ("linux-x86_64", "linux-aarch64", "macos-arm64", "windows-amd64"):  # jaxlib: cp311-cp314
        assert "jax" in names(applicable(peers, target("3.11", platform)))
        assert "jax" not in names(applicable(peers, target("3.10", platform)))
        assert "jax" not in names(applicable(peers, target("3.15", platform)))
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
    # cvxopt 1.3.3: no wheel for 3.15, none for 3.13+ on macOS
    assert "cvxopt" in names(applicable(peers, target("3.12", "macos-arm64")))
    assert "cvxopt" not in names(applicable(peers, target("3.13", "macos-arm64")))
    assert "cvxopt" in names(applicable(peers, target("3.14", "windows-amd64")))
    assert "cvxopt" not in names(applicable(peers, target("3.15", "linux-x86_64")))


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
    assert row["Windows amd64"][5] == "g2opy; no qdldl, numba, jupytext"


def test_the_student_readme_carries_the_requirements_table():
    table = requirements_table()
    assert table in STUDENT_README.read_text(encoding="utf-8"), (
        f"{STUDENT_README.relative_to(ROOT)} does not carry the current requirements table: paste the output of "
        '`python -m autograder.release.platforms --table` into its "Requirements" section (the table is built from the '
        "markers of pyproject.toml)"
    )


def test_main_prints_the_table(capsys):
    assert platforms.main(["--table"]) == 0
    assert capsys.readouterr().out == requirements_table()


def test_resolve_reports_the_resolvers_complaint(monkeypatch):
    stderr = (
        "  x No solution found when resolving dependencies:\n"
        "  `-> Because qdldl==0.1.9.post1 has no usable wheels and you require qdldl>=0.1.9, we can conclude that "
        "your requirements are unsatisfiable.\n"
    )
    calls = []

    def fake_run(command, **options):
        calls.append((command, options))
        return subprocess.CompletedProcess(command, 1, stdout="", stderr=stderr)

    monkeypatch.setattr(platforms.subprocess, "run", fake_run)
    with pytest.raises(ResolutionError) as raised:
        resolve(["qdldl>=0.1.9"], target("3.15", "linux-aarch64"))
    message = str(raised.value)
    assert "Python 3.15 on linux-aarch64" in message and "no usable wheels" in message
    ((command, options),) = calls
    assert command[command.index("--python-version") + 1] == "3.15"
    assert command[command.index("--python-platform") + 1] == "aarch64-manylinux_2_28"
    assert command[command.index("--only-binary") + 1] == ":all:" and "--no-deps" not in command
    assert options["input"] == "qdldl>=0.1.9" and options["env"]["MACOSX_DEPLOYMENT_TARGET"] == "14.0"


def test_resolve_reads_the_pinned_lines(monkeypatch):
    pinned = "colorama==0.4.6\nIPython_Pygments-Lexers==1.1.1\n# a comment\ntqdm==4.67.1 ; sys_platform == 'win32'\n\n"
    monkeypatch.setattr(
        platforms.subprocess, "run", lambda command, **options: subprocess.CompletedProcess(command, 0, pinned, "")
    )
    assert resolve(["tqdm"], target("3.12", "windows-amd64")) == {
        "colorama": "0.4.6",
        "ipython-pygments-lexers": "1.1.1",
        "tqdm": "4.67.1",
    }


def test_resolve_of_nothing_runs_no_resolver(monkeypatch):
    monkeypatch.setattr(platforms.subprocess, "run", lambda *args, **options: pytest.fail("ran the resolver"))
    assert resolve([], target("3.12", "linux-x86_64")) == {}


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
        # the transitive dependencies' markers are the target's, not this interpreter's
        assert ("colorama" in result.core) == (result.target.platform == "windows-amd64"), result.target  # tqdm's
        assert ("appnope" in result.core) == (result.target.platform == "macos-arm64"), result.target  # ipykernel's
    print(f"{len(results)} targets resolved in {time.monotonic() - start:.0f} s")
