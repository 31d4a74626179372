"""Subcommands of ``python -m course`` that live above the framework, such as the instructor's ``release``.

The framework defines the seam and imports none of them: a package registers a subcommand as an entry
point of the group ``course.commands`` (``[project.entry-points."course.commands"]`` in its
``pyproject.toml``), ``NAME = "module:add_parser"``, where ``add_parser(subparsers)`` adds the subcommand
``NAME`` to the command line's subparsers and sets its ``func(args) -> int``. The instructor's tree
registers ``release`` (``autograder.release.command``); a student tree registers nothing.

An entry point whose module this tree does not hold (a student tree run by an interpreter that has the
instructor's installation) is left out. A command that this checkout's ``pyproject.toml`` declares but that
the running Python has not registered (the checkout is not installed, or was installed before the entry
point was added) is not a usage error but an installation's: :func:`unregistered` says how to install it.
"""

import sys
from collections.abc import Callable, Iterable
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path
from typing import NamedTuple

from course.core.impl import REPO_ROOT

GROUP = "course.commands"
#: the checkout's project file, read only to explain a command it declares that is not registered
PYPROJECT = REPO_ROOT / "pyproject.toml"


class Plugin(NamedTuple):
    """A registered subcommand: its name and the function that adds it to the subparsers."""

    name: str
    add_parser: Callable


def _absent_here(entry: EntryPoint, exc: ImportError) -> bool:
    """Whether loading ``entry`` failed because this tree does not hold its module (or a package above it),
    rather than because of an error inside a module it holds."""
    missing = getattr(exc, "name", None) or ""
    return bool(missing) and (entry.module == missing or entry.module.startswith(missing + "."))


def registered(found: Iterable[EntryPoint] | None = None) -> list:
    """The :class:`Plugin` of every ``course.commands`` entry point this tree holds, by name."""
    plugins: dict = {}
    for entry in sorted(entry_points(group=GROUP) if found is None else found, key=lambda e: e.name):
        if entry.name in plugins:  # the same distribution seen twice on the path
            continue
        try:
            add_parser = entry.load()
        except ImportError as exc:
            if _absent_here(entry, exc):
                continue
            raise
        plugins[entry.name] = Plugin(entry.name, add_parser)
    return list(plugins.values())


def declared(pyproject: Path = PYPROJECT) -> dict:
    """``{name: "module:attr"}`` of the ``course.commands`` entry points in ``pyproject`` (empty where it is
    missing, unreadable, or no TOML reader is installed)."""
    try:
        if sys.version_info >= (3, 11):
            import tomllib
        else:
            import tomli as tomllib
        project = tomllib.loads(Path(pyproject).read_text(encoding="utf-8")).get("project", {})
    except (ImportError, OSError, ValueError):
        return {}
    group = project.get("entry-points", {}).get(GROUP, {})
    return {str(name): str(value) for name, value in group.items()} if isinstance(group, dict) else {}


def unregistered(argv: list, registered_names: Iterable[str], pyproject: Path = PYPROJECT) -> str | None:
    """The error for a command line whose subcommand this checkout declares but this Python has not
    registered, saying how to install it; None for any other command line (argparse judges those)."""
    command = next((arg for arg in argv if not arg.startswith("-")), None)
    if command is None or command in set(registered_names):
        return None
    target = declared(pyproject).get(command)
    if target is None:
        return None
    return (f"`python -m course {command}` comes from {target} (the entry point {command!r} of "
            f'[project.entry-points."{GROUP}"] in {pyproject}), which this Python ({sys.executable}) '
            f"has not registered: the checkout is not installed, or was installed before that entry point was "
            f"added. Install it: `{sys.executable} -m pip install -e {Path(pyproject).parent}` (or `make venv`)")
