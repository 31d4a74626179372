"""Every exercise lists the edges of its contract in its docstring, its check module lists the
same edges with a predicate on a call's inputs, and some check input sits on each: in the public
set, or in every hidden set (whatever the seed)."""

import importlib

import pytest

from autograder import oracle
from autograder.checks import ORDER
from autograder.checks.edges import HEADING, listed, reached

EXERCISES = sorted(name for name in ORDER if importlib.util.find_spec(f"solutions.{name}") is not None)
HIDDEN_SEEDS = (oracle.DEFAULT_HIDDEN_SEED, 1, 20261127)


def test_every_exercise_has_a_check_module_of_its_name():
    assert len(EXERCISES) >= 20


@pytest.mark.parametrize("name", EXERCISES)
def test_the_docstring_and_the_checks_list_the_same_edges(name):
    docstring = importlib.import_module(f"solutions.{name}").__doc__
    module = importlib.import_module(f"autograder.checks.{name}")
    written = listed(docstring)
    assert written, f"solutions/{name}.py: its docstring lists no '{HEADING}'"
    declared = [edge.name for edge in getattr(module, "EDGES", ())]
    assert sorted(written) == sorted(declared), f"solutions/{name}.py against autograder/checks/{name}.py EDGES"
    assert len(set(declared)) == len(declared)


@pytest.mark.parametrize("name", EXERCISES)
def test_every_edge_has_a_public_input_or_one_in_every_hidden_set(name):
    module = importlib.import_module(f"autograder.checks.{name}")
    public = [call for check in module.CHECKS for call in check.calls(None)]
    hidden = {seed: [call for check in module.CHECKS for call in check.calls(seed)] for seed in HIDDEN_SEEDS}
    missing = [edge.name for edge in module.EDGES
               if not reached(edge, public) and not all(reached(edge, calls) for calls in hidden.values())]
    assert not missing, f"autograder/checks/{name}.py: no input on {missing}"


def test_the_list_is_read_as_written():
    text = f"""Intro.

    {HEADING} (each is a check input):
    - one edge (M = 1)
    - information diagonal but
      anisotropic
    Not an item.
    """
    assert listed(text) == ["one edge (M = 1)", "information diagonal but anisotropic"]
    assert listed("no list here") == []
