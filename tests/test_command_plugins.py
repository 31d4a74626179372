"""Subcommands registered from above the framework (``course.commands`` entry points): the instructor's
``release`` reaches ``python -m course`` without ``course/`` importing the grader."""

from importlib.metadata import EntryPoint

import pytest

from course.app import cli, command_plugins

ROOT = command_plugins.REPO_ROOT


def _entry(name, value):
    return EntryPoint(name=name, value=value, group=command_plugins.GROUP)


def test_this_checkout_registers_release_from_the_grader():
    declared = command_plugins.declared()
    assert declared == {"release": "autograder.release.command:add_parser"}
    names = [plugin.name for plugin in command_plugins.registered()]
    assert names == ["release"], "the checkout's entry points are not installed: `pip install -e .`"


def test_an_entry_point_whose_module_this_tree_lacks_is_left_out():
    found = command_plugins.registered([_entry("release", "autograder.no_such_package.command:add_parser"),
                                        _entry("datasets2", "course.app.cli:build_parser")])
    assert [plugin.name for plugin in found] == ["datasets2"] and found[0].add_parser is cli.build_parser


def test_an_import_error_inside_a_held_module_is_not_hidden(tmp_path, monkeypatch):
    (tmp_path / "broken_plugin.py").write_text("import no_such_module_anywhere\ndef add_parser(sub): pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ModuleNotFoundError, match="no_such_module_anywhere"):
        command_plugins.registered([_entry("broken", "broken_plugin:add_parser")])


def test_a_declared_command_not_registered_says_how_to_install(tmp_path):
    pyproject = tmp_path / "pyproject.toml"
    pyproject.write_text('[project]\nname = "x"\n\n[project.entry-points."course.commands"]\n'
                         'release = "autograder.release.command:add_parser"\n')
    message = command_plugins.unregistered(["release", "--check"], [], pyproject)
    assert "autograder.release.command:add_parser" in message and str(pyproject) in message
    assert f"-m pip install -e {tmp_path}" in message and "make venv" in message
    assert command_plugins.unregistered(["release"], ["release"], pyproject) is None
    assert command_plugins.unregistered(["compare", "curve"], [], pyproject) is None  # argparse's to judge
    assert command_plugins.unregistered(["--help"], [], pyproject) is None
    assert command_plugins.unregistered(["release"], [], tmp_path / "absent.toml") is None


def test_release_without_the_installed_entry_point_names_the_install(monkeypatch, capsys):
    """The checkout on ``sys.path`` alone (``pythonpath = .``), not installed: no ``release`` is registered."""
    monkeypatch.setattr(command_plugins, "entry_points", lambda group: [])
    assert cli.main(["release", "--check"]) == 2
    err = capsys.readouterr().err
    assert "has not registered" in err and "pip install -e" in err and str(ROOT / "pyproject.toml") in err
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert "release" not in capsys.readouterr().out


def test_release_is_the_same_command_both_ways(capsys):
    with pytest.raises(SystemExit):
        cli.main(["release", "--help"])
    through_course = capsys.readouterr().out
    from autograder.release import command

    with pytest.raises(SystemExit):
        command.main(["--help"])
    direct = capsys.readouterr().out
    options = lambda text: sorted(word for word in text.split() if word.startswith("--"))  # noqa: E731
    assert options(through_course) == options(direct) and "--gradescope" in direct
