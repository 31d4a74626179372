"""An exercise imports only what its contract allows (``autograder/allowed_imports.py``): the
``Allowed imports:`` line of every exercise, the reading of a file's imports, and that no correct or
buggy variant of ``tests/student_variants`` is refused (they are graded on their code)."""

import json

import pytest

from autograder import allowed_imports
from autograder.allowed_imports import CONTRACT_FILE, contract_of, contract_text, load_contracts, refusals, scan
from course.core.impl import REPO_ROOT
from student_variants import SOLUTIONS, VARIANTS, apply

CONTRACTS = load_contracts()


def test_every_exercise_has_a_contract_and_the_shipped_file_is_fresh():
    modules = sorted(p.stem for p in SOLUTIONS.glob("*.py") if p.name != "__init__.py")
    assert sorted(CONTRACTS) == modules
    assert CONTRACT_FILE.read_text() == contract_text(SOLUTIONS), "run `python -m course release`"
    for module, entries in CONTRACTS.items():
        assert entries[:2] == ("numpy", "scipy"), module
        stub = (REPO_ROOT / "exercises" / f"{module}.py").read_text()
        assert contract_of(stub) == entries, f"exercises/{module}.py: the stub says its contract too"


def test_the_contracts_name_exactly_what_the_reference_imports_from_the_framework():
    for module, entries in CONTRACTS.items():
        source = (SOLUTIONS / f"{module}.py").read_text()
        imported = {r.what for r in scan(source, ("numpy", "scipy"))}
        framework = set(entries[2:])
        assert {w.rsplit(".", 1)[0] if w.startswith("course.") else w for w in imported} == framework, module


def test_the_reference_and_the_stubs_are_not_refused():
    assert refusals(SOLUTIONS) == {}
    assert refusals(REPO_ROOT / "exercises") == {}


@pytest.mark.parametrize("name", sorted(VARIANTS))
def test_no_variant_is_refused(name):
    """The known mistakes and the correct-but-different versions are graded on their code."""
    variant = VARIANTS[name]
    module = variant.file[:-3]
    text = apply((SOLUTIONS / variant.file).read_text(), variant)
    assert scan(text, CONTRACTS[module]) == [], name


ALLOWED = ("numpy", "scipy", "course.solver.unique", "course.solver.schur_reduction", ".pose_graph_edge")


@pytest.mark.parametrize("source", [
    "import numpy as np",
    "import numpy.linalg",
    "from scipy.sparse import linalg as spla",
    "import scipy.sparse as sp",
    "from course.solver.unique import unique_inverse",
    "from course.solver import unique",
    "import course.solver.unique as unique",
    "from . import pose_graph_edge",
    "from .pose_graph_edge import edge_error_and_jacobians",
    "import math, functools, itertools\nfrom dataclasses import dataclass\nfrom typing import NamedTuple",
    "from collections import deque",
    "m = __import__('numpy')",
    "def f():\n    import numpy as np\n    return np",
])
def test_allowed(source):
    assert scan(source, ALLOWED) == []


@pytest.mark.parametrize("source, what", [
    ("from course.backends.factorgraph.jax_factors import JaxJacobians", "course.backends.factorgraph.jax_factors"),
    ("import course.solver.per_pattern as pp", "course.solver.per_pattern"),
    ("from course.solver import per_pattern", "course.solver.per_pattern"),
    ("from course import solver", "course.solver"),
    ("from course.solver.schur_reduction import _pattern", "course.solver.schur_reduction._pattern"),
    ("import course.solver.unique", "course.solver.unique"),  # binds `course`: the whole framework
    ("from solutions import pose_graph_edge", "solutions.pose_graph_edge"),
    ("from exercises.pose_graph_edge import edge_error_and_jacobians", "exercises.pose_graph_edge"),
    ("from autograder.oracle import compute", "autograder.oracle"),
    ("from . import pose_graph_fast", ".pose_graph_fast"),
    ("from .helpers import shortcut", ".helpers"),
    ("from .. import course", ".."),
    ("import jax.numpy as jnp", "jax"),
    ("import gtsam", "gtsam"),
    ("import pyceres", "pyceres"),
    ("import g2o", "g2o"),
    ("import pycolmap", "pycolmap"),
    ("import importlib", "importlib"),
    ("import os", "os"),
    ("import sys", "sys"),
    ("import subprocess", "subprocess"),
    ("import ctypes", "ctypes"),
    ("import inspect", "inspect"),
    ("def f():\n    from course.problems.vio.ape import umeyama\n    return umeyama", "course.problems.vio.ape"),
    ("m = __import__('course.backends')", "course.backends"),
    ("m = __import__(name)", "__import__(...)"),
    ("x = something.import_module('course.app')", "course.app"),
    ("x = something.import_module(name)", "import_module(...)"),
    ("exec('import os')", "exec(...)"),
    ("eval(text)", "eval(...)"),
    ("m = __builtins__", "__builtins__"),
    ("g = f.__globals__", ".__globals__"),
])
def test_refused(source, what):
    found = scan(source, ALLOWED)
    assert found and found[0].what.startswith(what), found
    assert found[0].line == (2 if source.startswith("def ") else 1)


def test_the_refusal_names_the_file_the_line_and_the_allowed_list(tmp_path):
    folder = tmp_path / "my_work"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    (folder / "pose_graph_edge.py").write_text(
        '"""mine"""\nimport numpy as np\n\nfrom course.backends.factorgraph.jax_factors import JaxJacobians\n')
    (folder / "notes.py").write_text("import os\n")  # not an exercise file: nothing imports it
    found = refusals(folder)
    assert list(found) == ["pose_graph_edge"]
    line = found["pose_graph_edge"]
    assert "\n" not in line
    assert line.startswith("my_work/pose_graph_edge.py:4: refused before running: imports "
                           "course.backends.factorgraph.jax_factors.JaxJacobians")
    assert "Allowed: numpy, scipy; from the standard library abc, " in line and "math" in line


def test_a_refused_file_becomes_an_unwritten_todo_naming_the_refusal(tmp_path):
    (tmp_path / "pose_graph_edge.py").write_text("x = 1\n")
    allowed_imports.neutralise(tmp_path, {"pose_graph_edge": "why it was refused"})
    namespace: dict = {}
    exec((tmp_path / "pose_graph_edge.py").read_text(), namespace)
    with pytest.raises(NotImplementedError, match="TODO pose_graph_edge.edge_error_and_jacobians: refused: why"):
        namespace["__getattr__"]("edge_error_and_jacobians")
    with pytest.raises(AttributeError):
        namespace["__getattr__"]("__path__")


def test_a_missing_or_malformed_contract_is_an_error_naming_the_file(tmp_path):
    with pytest.raises(allowed_imports.ContractError, match="x.py: the module docstring has no 'Allowed imports:'"):
        contract_of('"""No contract."""\n', "x.py")
    with pytest.raises(allowed_imports.ContractError, match="malformed"):
        contract_of('"""Allowed imports: numpy, not a module."""\n', "x.py")
    path = tmp_path / "imports.json"
    path.write_text(json.dumps({"format": 0}))
    with pytest.raises(allowed_imports.ContractError, match="not a contract file"):
        load_contracts(path)
