"""The generated pages: docs/commands.md is every command's own ``--help`` (course.app.commands_page) and
docs/measured.md the render of docs/measured/ (course.app.measured_page), whose every file names the
machine it was measured on and the command that reproduces it; the commands the measured page keeps
without a file are commands the command line takes."""

import argparse
import copy
import importlib.util
import json
import re
import shlex
import sys

import pytest

from course.app import benchmark_suite, commands_page, measured_page
from course.app.cli import build_parser


def flags(page: str) -> dict:
    """``{command: set of its --options}`` of a commands page."""
    sections = re.findall(r"^## `(.*?)`\n\n```text\n(.*?)```", page, re.S | re.M)
    return {command: set(re.findall(r"(?<![\w-])--[a-z][\w-]*", text)) for command, text in sections}


def test_the_commands_page_is_the_commands_help():
    page = commands_page.PAGE.read_text(encoding="utf-8")
    written_with = re.search(r"\(Python (\d+\.\d+)\)", page).group(1)
    rendered = commands_page.render()
    if written_with == f"{sys.version_info.major}.{sys.version_info.minor}":
        assert page == rendered, f"docs/commands.md is stale: run `{commands_page.COMMAND}`"
    else:  # argparse lays the help out differently from one Python to the next: the same commands and options
        assert flags(page) == flags(rendered), f"docs/commands.md is stale: run `{commands_page.COMMAND}`"


def test_the_commands_page_has_every_subcommand_of_the_course():
    parser = build_parser()
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    page = commands_page.PAGE.read_text(encoding="utf-8")
    for name in sub.choices:
        assert f"## `python -m course {name}`" in page, name


def test_subcommands_are_read_from_the_usage_or_the_command_list():
    assert commands_page.subcommands("usage: x [-h] {a,b-c} ...\n\nmore", "x") == ["a", "b-c"]
    listing = "usage: x [-h] COMMAND ...\n\npositional arguments:\n  COMMAND\n    demo      d\n    ape       a\n\nx"
    assert commands_page.subcommands(listing, "x") == ["demo", "ape"]
    with pytest.raises(RuntimeError, match="lists no subcommand"):
        commands_page.subcommands("usage: x [-h]\n\noptions:\n  -h", "x")


def test_the_measured_page_is_the_render_of_its_files():
    page = measured_page.PAGE.read_text(encoding="utf-8")
    assert page == measured_page.render(), f"docs/measured.md is stale: run `{measured_page.COMMAND}`"


def test_every_measured_file_names_its_machine_and_command():
    files = sorted(measured_page.FOLDER.glob("*.json"))
    assert len(files) >= 2
    page = measured_page.PAGE.read_text(encoding="utf-8")
    for path in files:
        data = benchmark_suite.load(path)
        machine = data["machine"]
        assert machine["cpu"] and machine["cores"] and machine["date"], path.name
        assert any(b.get("architecture") and b.get("internal_api") for b in machine["blas"]), path.name
        assert machine["command"].startswith("python -m course benchmark --suite"), path.name
        assert f"`docs/measured/{path.name}`" in page
        words = shlex.split(machine["command"])
        build_parser().parse_args(words[3:])  # a command the command line takes
    assert any("shared machine" in json.loads(p.read_text()).get("note", "") for p in files)


def test_a_section_shows_the_ratio_against_the_peer_of_the_same_run(tmp_path):
    data = json.loads(next(measured_page.FOLDER.glob("suite-*-bal-*.json")).read_text())
    data["note"] = "measured on a shared machine"
    data["machine"]["command"] = "python -m course benchmark --suite --only bal --json /tmp/x.json --note 'a b'"
    (tmp_path / "suite-x.json").write_text(json.dumps(data))
    (tmp_path / "notes.md").write_text("## Notes\n")
    text = measured_page.render(tmp_path)
    row = data["rows"][0]
    assert f"| {row['name']} | {row['ratio']:.3f} ({row['min']:.3f} to {row['max']:.3f}) | " in text
    assert "measured on a shared machine" in text and text.endswith("## Notes\n")
    assert "`python -m course benchmark --suite --only bal --json new.json --note 'a b'`" in text
    assert "SkylakeX kernel" in text and data["machine"]["cpu"] in text
    broken = copy.deepcopy(data)
    del broken["rows"][0]["ratio"]
    (tmp_path / "suite-x.json").write_text(json.dumps(broken))
    with pytest.raises(ValueError, match=r"suite-x\.json: rows\[0\].*no field 'ratio'"):
        measured_page.render(tmp_path)


def test_the_commands_kept_without_a_file_are_the_command_line_s():
    notes = (measured_page.FOLDER / measured_page.NOTES).read_text(encoding="utf-8")
    table = [line for line in notes.split("## The measurements without a file", 1)[1].split("\n## ", 1)[0]
             .splitlines() if line.startswith("| ") and not line.startswith("| what")]
    commands = [c for line in table for c in re.findall(r"`(python -m [^`]+)`", line)]
    assert len(table) >= 10 and len(commands) >= len(table)
    for command in commands:
        words = shlex.split(command)
        if words[2] == "course":
            build_parser().parse_args(words[3:])
        else:
            assert importlib.util.find_spec(words[2]) is not None, command
