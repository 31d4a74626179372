"""An assignment's student tree as its student uses it: the README's hint commands name an exercise
of the tree and print its hints (from ``exercises/hints.json``), and pytest labels an exercise extra
credit as the assignment's configuration says (``optional``), never by the check's name."""

import json
import os
import re
import shlex
import subprocess

import pytest

from autograder.checks import all_checks
from autograder.course_config import load
from autograder.release import assignment as handout
from autograder.release.stubs import render
from course.core.impl import REPO_ROOT

COURSE = load()


@pytest.fixture(scope="module")
def stubs():
    return render(REPO_ROOT / "solutions")


def _run(python, tree, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL", "AUTOGRADER"))}
    env["PYTHONPATH"] = str(tree)
    return subprocess.run([python, *args], cwd=tree, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("name", ["ch1", "ch3", "ch7"])
def test_the_readme_s_hint_commands_work_in_an_assignment_tree(tmp_path, stubs, python, name):
    assignment = COURSE.assignment(name)
    tree = tmp_path / "tree"
    handout.write_student_tree(tree, COURSE, assignment, stubs)
    commands = re.findall(r"`\.venv/bin/python (-m autograder hint [\w.]+ \d)`", (tree / "README.md").read_text())
    commands += re.findall(r"`(hint [\w.]+ \d)`", (tree / "README.md").read_text())
    assert len(commands) >= 2, commands
    for command in commands:
        argv = shlex.split(command)
        argv = argv if argv[0] == "-m" else ["-m", "autograder", *argv]
        done = _run(python, tree, *argv)
        assert done.returncode == 0 and "hint" in done.stdout, f"{command}\n{done.stdout}\n{done.stderr}"
    graded = set(assignment.modules)
    first = commands[0].split()[3]
    assert first in graded, commands
    shipped = set(json.loads((tree / "exercises" / "hints.json").read_text()))
    assert graded <= shipped and not shipped & set(assignment.solved)


def test_no_check_calls_itself_optional():
    assert not [c.name for c in all_checks() if "optional" in c.name.lower()]


def test_pytest_says_extra_credit_only_where_the_assignment_makes_it_optional(tmp_path, stubs, python):
    tree = tmp_path / "tree"
    handout.write_student_tree(tree, COURSE, COURSE.assignment("ch2"), stubs)

    def fast_items():
        done = _run(python, tree, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider")
        items = [line for line in done.stdout.splitlines() if "pose_graph_fast" in line]
        assert items, done.stdout[-2000:] + done.stderr[-2000:]
        return items

    assert all("(extra credit)" in item and "optional" not in item for item in fast_items())
    config = tree / "autograder" / "course.toml"
    config.write_text(config.read_text().replace('optional = ["pose_graph_fast"]\n', ""))
    assert all("extra credit" not in item and "optional" not in item for item in fast_items())
