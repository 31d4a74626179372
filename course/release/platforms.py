"""Where the course installs: the supported (Python, platform) targets and a check that they get wheels.

Each target has the PEP 508 marker environment of that Python on that platform, so the markers of
``pyproject.toml`` say what installs there (``applicable``), and the pip ``--platform`` tags, so pip
can resolve the requirements against the package index's wheels for it without being there
(``resolve``, ``check``). ``requirements_table`` turns the markers alone into the Markdown table of
the student README's "Requirements" section.

This is a development tool, run on Python >= 3.11 (it reads ``pyproject.toml`` with ``tomllib``)::

    python -m course.release.platforms           # resolve every target on the index, one line each
    python -m course.release.platforms --table   # print the README's table (markers only, no network)
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"

PYTHONS = ("3.10", "3.11", "3.12", "3.13", "3.14", "3.15")


def _manylinux(arch: str) -> tuple[str, ...]:
    # pip takes a manylinux_2_X tag literally (no expansion to older glibc), so name each one
    return (*(f"manylinux_2_{minor}_{arch}" for minor in range(28, 16, -1)), f"manylinux2014_{arch}")


# platform key: (label, pip --platform tags, the marker variables that do not depend on the Python)
_PLATFORMS: dict[str, tuple[str, tuple[str, ...], dict[str, str]]] = {
    "linux-x86_64": (
        "Linux x86_64 (glibc 2.28+)",
        _manylinux("x86_64"),
        {
            "sys_platform": "linux",
            "platform_system": "Linux",
            "platform_machine": "x86_64",
            "os_name": "posix",
            "platform_release": "6.0",
            "platform_version": "#1 SMP",
        },
    ),
    "linux-aarch64": (
        "Linux aarch64 (glibc 2.28+)",
        _manylinux("aarch64"),
        {
            "sys_platform": "linux",
            "platform_system": "Linux",
            "platform_machine": "aarch64",
            "os_name": "posix",
            "platform_release": "6.0",
            "platform_version": "#1 SMP",
        },
    ),
    "macos-arm64": (
        "macOS 14+ arm64",
        # pip adds the older macOS versions (macosx_13_0 ... macosx_11_0) itself
        ("macosx_14_0_arm64",),
        # macOS 14 is Darwin 23
        {
            "sys_platform": "darwin",
            "platform_system": "Darwin",
            "platform_machine": "arm64",
            "os_name": "posix",
            "platform_release": "23.0.0",
            "platform_version": "Darwin Kernel Version 23.0.0",
        },
    ),
    "windows-amd64": (
        "Windows amd64",
        ("win_amd64",),
        {
            "sys_platform": "win32",
            "platform_system": "Windows",
            "platform_machine": "AMD64",
            "os_name": "nt",
            "platform_release": "10",
            "platform_version": "10.0.19045",
        },
    ),
}


@dataclass(frozen=True)
class Target:
    """One supported CPython on one platform."""

    python: str  # "3.10" ... "3.15"
    platform: str  # a key of the platforms: "linux-x86_64", "linux-aarch64", "macos-arm64", "windows-amd64"
    label: str  # for people: "macOS 14+ arm64"
    tags: tuple[str, ...]  # pip --platform tags
    environment: Mapping[str, str] = field(hash=False, compare=False, repr=False)  # PEP 508 marker variables

    def __str__(self) -> str:
        return f"Python {self.python} on {self.platform}"


def target(python: str, platform: str) -> Target:
    """The ``Target`` for a Python version ("3.12") and a platform key ("macos-arm64")."""
    label, tags, variables = _PLATFORMS[platform]
    full_version = f"{python}.0"
    environment = {
        **variables,
        "python_version": python,
        "python_full_version": full_version,
        "implementation_name": "cpython",
        "implementation_version": full_version,
        "platform_python_implementation": "CPython",
    }
    return Target(python, platform, label, tags, environment)


TARGETS: tuple[Target, ...] = tuple(target(python, platform) for platform in _PLATFORMS for python in PYTHONS)


def requirements(extra: str | None = None, pyproject: Path = PYPROJECT) -> list[str]:
    """The requirement strings of the core (``extra=None``) or of an optional extra, markers included."""
    import tomllib  # Python >= 3.11, as this tool is

    project = tomllib.loads(Path(pyproject).read_text(encoding="utf-8"))["project"]
    if extra is None:
        return list(project.get("dependencies", []))
    return list(project["optional-dependencies"][extra])


def applicable(requirements: Iterable[str], target: Target) -> list[str]:
    """The requirements whose markers hold on ``target``, without their markers (name, extras, specifier)."""
    kept = []
    for text in requirements:
        requirement = Requirement(text)
        if requirement.marker is not None and not requirement.marker.evaluate(dict(target.environment)):
            continue
        extras = f"[{','.join(sorted(requirement.extras))}]" if requirement.extras else ""
        where = f" @ {requirement.url}" if requirement.url else str(requirement.specifier)
        kept.append(f"{requirement.name}{extras}{where}")
    return kept


def _names(requirements: Iterable[str]) -> list[str]:
    return [Requirement(text).name for text in requirements]


class ResolutionError(RuntimeError):
    """pip found no set of wheels for the requirements on a target."""


def _stderr_tail(stderr: str, lines: int = 12) -> str:
    # drop pip's notes about find-links / index locations that do not exist on this machine
    kept = [line for line in stderr.splitlines() if line.strip() and not line.startswith("WARNING: Location")]
    return "\n".join(kept[-lines:])


def _pip_report(requirements: Sequence[str], target: Target, timeout: float, deps: bool) -> list[dict[str, Any]]:
    """The "install" list of pip's installation report for ``requirements`` on ``target``."""
    platforms = [f"--platform={tag}" for tag in target.tags]
    with tempfile.TemporaryDirectory(prefix="course-platforms-") as scratch:
        command = [
            sys.executable, "-m", "pip", "install", "--dry-run", "--quiet", "--ignore-installed",
            "--only-binary=:all:", "--python-version", target.python, *platforms, "--target", scratch,
            "--report", "-", *([] if deps else ["--no-deps"]), *requirements,
        ]  # fmt: skip
        try:
            done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
        except subprocess.TimeoutExpired as error:
            raise ResolutionError(
                f"{target}: pip took more than {timeout:.0f} s for {' '.join(requirements)}"
            ) from error
    if done.returncode != 0:
        tail = _stderr_tail(done.stderr)
        raise ResolutionError(f"{target}: pip finds no wheels for {' '.join(requirements)}:\n{tail}")
    install: list[dict[str, Any]] = json.loads(done.stdout)["install"]
    return install


def _missed(install: list[dict[str, Any]], target: Target) -> list[str]:
    """The dependencies, without markers, that the target needs and pip left out of ``install``."""
    present = {canonicalize_name(item["metadata"]["name"]) for item in install}
    missed = []
    for item in install:
        extras = ["", *item.get("requested_extras", [])]
        for text in item["metadata"].get("requires_dist", []):
            requirement = Requirement(text)
            if canonicalize_name(requirement.name) in present or requirement.marker is None:
                continue
            if any(requirement.marker.evaluate({**target.environment, "extra": extra}) for extra in extras):
                requirement.marker = None
                missed.append(str(requirement))
    return missed


def resolve(requirements: Sequence[str], target: Target, timeout: float = 300, deps: bool = True) -> dict[str, str]:
    """What ``pip install REQUIREMENTS`` would install on ``target``: ``{name: version}`` (names normalized).

    pip resolves against the index's metadata, taking wheels only and downloading none but the
    metadata it needs (``deps=False``: the requirements alone). The requirements' own markers are not
    looked at here: pass them through ``applicable`` first. Raises ``ResolutionError`` when pip finds
    no solution, or takes longer than ``timeout`` seconds for one run.
    """
    if not requirements:
        return {}
    # pip evaluates the markers of *transitive* dependencies against the interpreter running it, not
    # against --python-version/--platform (only the direct requirements' markers are the target's,
    # through ``applicable``). So a dependency that a package wants only on the target (colorama on
    # Windows, appnope on macOS, tomli below 3.11) is left out: read each installed package's
    # Requires-Dist from the report, and resolve again with those the target needs added, until none
    # is missing. (The reverse, a dependency pip adds for this interpreter that the target would not
    # install, stays in: it can only make the check stricter.)
    wanted = list(requirements)
    for _ in range(5):
        install = _pip_report(wanted, target, timeout, deps)
        missed = _missed(install, target) if deps else []
        if not missed:
            break
        wanted += missed
    return {canonicalize_name(item["metadata"]["name"]): item["metadata"]["version"] for item in install}


@dataclass
class Result:
    """The resolution of the core and of the peers on one target: versions, or pip's complaint."""

    target: Target
    peer_names: list[str]  # the peers whose markers hold on the target
    core: dict[str, str] | None = None
    core_error: str | None = None
    peers: dict[str, str] | None = None
    peers_error: str | None = None

    @property
    def ok(self) -> bool:
        return self.core_error is None and self.peers_error is None


def check(
    targets: Iterable[Target] = TARGETS, workers: int = 4, timeout: float = 300, pyproject: Path = PYPROJECT
) -> list[Result]:
    """Resolve the core and the ``peers`` extra on every target, ``workers`` pips at a time.

    The peers are resolved together with the core, as ``pip install .[peers]`` does, so a peer that
    pins a core package the core cannot have fails too. When that succeeds the core resolves as well
    (the same wheels do), and ``Result.core`` is that resolution; otherwise, or when the markers admit
    no peer, the core is resolved alone, to tell whose fault it is. Returns one ``Result`` a target, in
    the order of ``targets``.
    """
    core, peers = requirements(pyproject=pyproject), requirements("peers", pyproject=pyproject)
    results = [Result(one, _names(applicable(peers, one))) for one in targets]

    def resolve_both(result: Result) -> None:
        admitted = applicable(peers, result.target)
        if admitted:
            try:
                result.peers = result.core = resolve(applicable(core, result.target) + admitted, result.target, timeout)
                return
            except ResolutionError as error:
                result.peers_error = str(error)
        else:
            result.peers = {}
        try:
            result.core = resolve(applicable(core, result.target), result.target, timeout)
        except ResolutionError as error:
            result.core_error = str(error)

    with ThreadPoolExecutor(max_workers=workers) as pool:
        for _ in pool.map(resolve_both, results):
            pass
    return results


def _cell(target: Target, core: Sequence[str], peers: Sequence[str]) -> str:
    peer_names = _names(peers)
    present = _names(applicable(peers, target))
    if present == peer_names:
        cell = "all peers"
    elif not present:
        cell = "no peers"
    else:
        cell = ", ".join(present)
    missing = sorted(set(_names(core)) - set(_names(applicable(core, target))), key=_names(core).index)
    if missing:
        cell += f"; no {', '.join(missing)}"
    return cell


def requirements_table(targets: Iterable[Target] = TARGETS, pyproject: Path = PYPROJECT) -> str:
    """The Markdown table of what installs where, from the markers alone (no network).

    One row a platform, one column a Python; a cell names the peers that install there ("all peers",
    "no peers", or their names) and, after "no", the core packages whose markers leave them out.
    """
    core, peers = requirements(pyproject=pyproject), requirements("peers", pyproject=pyproject)
    targets = list(targets)
    pythons = sorted({one.python for one in targets}, key=lambda version: tuple(map(int, version.split("."))))
    platforms = list(dict.fromkeys(one.platform for one in targets))
    by_key = {(one.platform, one.python): one for one in targets}
    lines = [
        "| platform | " + " | ".join(f"Python {python}" for python in pythons) + " |",
        "|---|" + "---|" * len(pythons),
    ]
    for platform in platforms:
        cells = []
        for python in pythons:
            one = by_key.get((platform, python))
            cells.append("-" if one is None else _cell(one, core, peers))
        label = next(one.label for one in targets if one.platform == platform)
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def _versions(versions: Mapping[str, str], names: Iterable[str]) -> str:
    return ", ".join(
        f"{name} {versions[canonicalize_name(name)]}" for name in names if canonicalize_name(name) in versions
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Print the README's table (``--table``) or resolve every target; 1 when one fails, else 0."""
    parser = argparse.ArgumentParser(prog="python -m course.release.platforms", description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", action="store_true", help="print the Markdown requirements table (no network)")
    parser.add_argument("--workers", type=int, default=4, help="pip processes at a time (default: 4)")
    options = parser.parse_args(argv)
    if options.table:
        print(requirements_table(), end="")
        return 0
    results = check(workers=options.workers)
    for result in results:
        where = f"{result.target.python:<5} {result.target.platform:<14}"
        if result.ok:
            assert result.core is not None and result.peers is not None
            peers = _versions(result.peers, result.peer_names) or "no peers"
            print(f"OK    {where} {_versions(result.core, ('numpy', 'scipy'))}; {peers}")
        else:
            print(f"FAIL  {where}")
            for error in (result.core_error, result.peers_error):
                if error is not None:
                    print("      " + error.replace("\n", "\n      "))
    failed = sum(not result.ok for result in results)
    print(f"{len(results) - failed} of {len(results)} targets resolve")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
