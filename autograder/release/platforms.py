"""Where the course installs: the supported (Python, platform) targets and a check that they get wheels.

Each target has the PEP 508 marker environment of that Python on that platform, so the markers of
``pyproject.toml`` say what installs there (``applicable``), and uv's name for the platform, so uv's
resolver (``uv pip compile``, a dev dependency) can resolve the requirements against the package
index's wheels for it without being there (``resolve``, ``check``). uv rather than pip: it judges
the transitive dependencies' markers by the target, not by the interpreter running it, and it takes
a fraction of a second of CPU a target where pip took ten. ``requirements_table`` turns the markers
alone into the Markdown table of the student README's "Requirements" section.

This is a development tool, run on Python >= 3.11 (it reads ``pyproject.toml`` with ``tomllib``)::

    python -m autograder.release.platforms           # resolve every target on the index, one line each
    python -m autograder.release.platforms --table   # print the README's table (markers only, no network)
"""

from __future__ import annotations

import argparse
import functools
import os
import subprocess
import sys
from collections.abc import Iterable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"

PYTHONS = ("3.10", "3.11", "3.12", "3.13", "3.14", "3.15")


# platform key: (label, uv --python-platform, the marker variables that do not depend on the Python);
# uv's manylinux_2_28 takes every older glibc tag too, its apple-darwin the MACOSX_DEPLOYMENT_TARGET
_PLATFORMS: dict[str, tuple[str, str, dict[str, str]]] = {
    "linux-x86_64": (
        "Linux x86_64 (glibc 2.28+)",
        "x86_64-manylinux_2_28",
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
        "aarch64-manylinux_2_28",
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
        "aarch64-apple-darwin",  # with MACOSX_DEPLOYMENT_TARGET=14.0: macosx_14_0 ... macosx_11_0
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
        "x86_64-pc-windows-msvc",
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
    resolver_platform: str  # uv --python-platform: "x86_64-manylinux_2_28", "aarch64-apple-darwin", ...
    environment: Mapping[str, str] = field(hash=False, compare=False, repr=False)  # PEP 508 marker variables

    def __str__(self) -> str:
        return f"Python {self.python} on {self.platform}"


def target(python: str, platform: str) -> Target:
    """The ``Target`` for a Python version ("3.12") and a platform key ("macos-arm64")."""
    label, resolver_platform, variables = _PLATFORMS[platform]
    full_version = f"{python}.0"
    environment = {
        **variables,
        "python_version": python,
        "python_full_version": full_version,
        "implementation_name": "cpython",
        "implementation_version": full_version,
        "platform_python_implementation": "CPython",
    }
    return Target(python, platform, label, resolver_platform, environment)


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
    """The resolver found no set of wheels for the requirements on a target."""


MACOS_DEPLOYMENT_TARGET = "14.0"  # the macos-arm64 label's "macOS 14+"


@functools.cache
def _uv() -> str:
    """The uv executable (a dev dependency: the check is a development tool)."""
    from uv import find_uv_bin

    return str(find_uv_bin())


def _compile(requirements: Sequence[str], target: Target, timeout: float, deps: bool) -> str:
    """The pinned ``name==version`` lines ``uv pip compile`` writes for ``requirements`` on ``target``."""
    command = [
        _uv(), "pip", "compile", "-", "--quiet", "--no-header", "--no-annotate", "--no-config",
        "--only-binary", ":all:", "--python-version", target.python, "--python-platform", target.resolver_platform,
        # this interpreter: else uv looks through every Python on the machine for one of the target's version
        "--python", sys.executable, *([] if deps else ["--no-deps"]),
    ]  # fmt: skip
    if os.environ.get("PIP_INDEX_URL"):  # the index pip is told to use, so both look at the same wheels
        command += ["--index-url", os.environ["PIP_INDEX_URL"]]
    environment = {**os.environ, "MACOSX_DEPLOYMENT_TARGET": MACOS_DEPLOYMENT_TARGET, "NO_COLOR": "1"}
    try:
        done = subprocess.run(
            command, input="\n".join(requirements), capture_output=True, text=True, timeout=timeout, env=environment
        )
    except subprocess.TimeoutExpired as error:
        raise ResolutionError(f"{target}: uv took more than {timeout:.0f} s for {' '.join(requirements)}") from error
    if done.returncode != 0:
        tail = "\n".join(line for line in done.stderr.splitlines()[-12:] if line.strip())
        raise ResolutionError(f"{target}: no set of wheels for {' '.join(requirements)}:\n{tail}")
    return done.stdout


def resolve(requirements: Sequence[str], target: Target, timeout: float = 300, deps: bool = True) -> dict[str, str]:
    """What ``pip install REQUIREMENTS`` would install on ``target``: ``{name: version}`` (names normalized).

    The resolver reads the index's metadata, takes wheels only and downloads none (``deps=False``: the
    requirements alone); the transitive dependencies' markers are the target's (colorama on Windows,
    appnope on macOS). The requirements' own markers are not looked at here: pass them through
    ``applicable`` first. Raises ``ResolutionError`` when there is no solution, or when one run takes
    longer than ``timeout`` seconds.
    """
    if not requirements:
        return {}
    pinned: dict[str, str] = {}
    for line in _compile(requirements, target, timeout, deps).splitlines():
        line = line.split("#")[0].strip()
        if line:
            name, _, version = line.partition("==")
            pinned[canonicalize_name(name.split("[")[0])] = version.split(";")[0].strip()
    return pinned


@dataclass
class Result:
    """The resolution of the core and of the peers on one target: versions, or the resolver's complaint."""

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
    """Resolve the core and the ``peers`` extra on every target, ``workers`` resolvers at a time.

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

    _uv()  # once, before the threads: uv's lookup reads sysconfig, which is not thread-safe
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for _ in pool.map(resolve_both, results):
            pass
    return results


#: core requirements that stand in for the standard library on older Pythons (tomli: ``tomllib`` from 3.11):
#: where their marker leaves them out nothing is missing
BACKPORTS = ("tomli",)


def _cell(target: Target, core: Sequence[str], peers: Sequence[str]) -> str:
    peer_names = _names(peers)
    present = _names(applicable(peers, target))
    if present == peer_names:
        cell = "all peers"
    elif not present:
        cell = "no peers"
    else:
        cell = ", ".join(present)
    missing = sorted(set(_names(core)) - set(_names(applicable(core, target))) - set(BACKPORTS),
                     key=_names(core).index)
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
    parser = argparse.ArgumentParser(prog="python -m autograder.release.platforms",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--table", action="store_true", help="print the Markdown requirements table (no network)")
    parser.add_argument("--workers", type=int, default=4, help="resolvers at a time (default: 4)")
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
