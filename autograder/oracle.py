# RELEASE: omit
"""The reference side of grading: instructor only, never in the student tree.

For a check and a seed (``None``: the public inputs; an integer: fresh hidden inputs)
this module builds the calls, runs them with ``solutions`` in this process (trusted
code) and evaluates the check's known mistakes (``autograder/mistakes/<module>.py``) on
the same inputs, giving an :class:`autograder.expected.Expected`. The release step writes
the public ones to ``autograder/expected/`` (:func:`render`); grading computes the hidden
ones before the first child starts.

The hidden seed comes from the environment variable ``AUTOGRADER_HIDDEN_SEED`` when set
(an instructor's own, e.g. baked into a Gradescope bundle), else :data:`DEFAULT_HIDDEN_SEED`.

With ``AUTOGRADER_ORACLE_CACHE`` set to a folder (the test suite sets it; off by default), each
:func:`compute` is kept there and read back by any process whose inputs, sources and numpy match
(:func:`_cache_key`): several grading runs of one test session compute the same hidden data once.
"""

import functools
import hashlib
import importlib
import os
import pickle
import platform
import sys
import tempfile
import threading
from collections import OrderedDict
from pathlib import Path

import numpy as np

from autograder.expected import Expected, dumps, same_data
from autograder.records import Outcome
from autograder.reference import reference_implementation
from autograder.rounding import moved_call, stable

DEFAULT_HIDDEN_SEED = 7211


def hidden_seed() -> int:
    text = os.environ.get("AUTOGRADER_HIDDEN_SEED", "").strip()
    if not text:
        return DEFAULT_HIDDEN_SEED
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"AUTOGRADER_HIDDEN_SEED must be an integer, got {text!r}") from None


def _mistake_catalogue(module: str) -> dict:
    try:
        catalogue = importlib.import_module(f"autograder.mistakes.{module}")
    except ModuleNotFoundError as exc:
        if exc.name != f"autograder.mistakes.{module}":
            raise
        return {}
    return getattr(catalogue, "MISTAKES", {})


#: outputs already computed, by what determines them (the calls' payloads): the last few only
_MEMO: "OrderedDict[tuple, object]" = OrderedDict()
_MEMO_SIZE = 64
_MEMO_LOCK = threading.Lock()


def forget() -> None:
    """Drop the remembered outputs (after the reference's libraries changed, in a test)."""
    with _MEMO_LOCK:
        _MEMO.clear()


def _digest(value) -> bytes:
    return hashlib.sha256(pickle.dumps(value, protocol=4)).digest()


def _memo(key: tuple, make):
    """``make()``, or what it returned before for the same ``key`` (the reference is deterministic)."""
    with _MEMO_LOCK:
        if key in _MEMO:
            _MEMO.move_to_end(key)
            return _MEMO[key]
    value = make()
    with _MEMO_LOCK:
        _MEMO[key] = value
        while len(_MEMO) > _MEMO_SIZE:
            _MEMO.popitem(last=False)
    return value


def _mistake_outputs(known, call, want) -> dict:
    return {key: [(np.asarray(v, dtype=float), why) for v, why in pairs] for key, pairs in known(call, want).items()}


class ReferenceFailed(RuntimeError):
    """The reference raised, or returned a malformed output, on one of a check's inputs: that check
    cannot be graded (:mod:`autograder.grade` reports it as not gradable and grades the others)."""


def reference_outcomes(calls) -> list:
    """The reference's :class:`Outcome` of each call (raises :class:`ReferenceFailed`): what
    :func:`compute` gives as ``reference``, without the known mistakes."""
    from autograder.child import run_calls

    solutions = reference_implementation()
    payloads = [c.payload() for c in calls]
    with np.errstate(all="ignore"):
        results = _memo(("reference", _digest(payloads)), lambda: run_calls(solutions, payloads))
    reference = []
    for call, result in zip(calls, results):
        if not isinstance(result, tuple):
            raise ReferenceFailed(f"the reference failed on {call.function} {call.where}: {result}")
        kind, fields = result
        reference.append(Outcome(fields=fields, kind=kind))
    return reference


def _mistakes_of(known, call, outcome) -> dict:
    from autograder.feedback import fields_of

    want, problem = fields_of(outcome, call)
    if problem:
        raise ReferenceFailed(f"the reference's output of {call.function} is malformed: {problem}")
    with np.errstate(all="ignore"):
        # the checks of one exercise often share their calls: each mistake is evaluated once per call
        key = ("mistakes", known, _digest(call.payload()))  # the function itself: closures share names
        return _memo(key, functools.partial(_mistake_outputs, known, call, want))


#: a folder where :func:`compute` keeps its results across processes; unset: no cache
CACHE_VARIABLE = "AUTOGRADER_ORACLE_CACHE"


@functools.lru_cache(maxsize=1)
def _fingerprint() -> bytes:
    """What decides the reference's numbers besides a call's inputs: the sources of the reference,
    the framework and the grader (checks, mistakes, rounding), and numpy's and scipy's builds."""
    import scipy

    packages = [Path(str(sys.modules[name].__file__)).resolve().parent
                for name in ("autograder", "course", reference_implementation().package)]
    digest = hashlib.sha256()
    for folder in packages:
        for path in sorted(folder.rglob("*.py")):
            digest.update(str(path.relative_to(folder)).encode() + b"\0" + path.read_bytes() + b"\0")
    config = np.show_config(mode="dicts") if np.lib.NumpyVersion(np.__version__) >= "1.26.0" else None
    digest.update(repr((np.__version__, scipy.__version__, config, sys.version, platform.machine())).encode())
    return digest.digest()


def _cache_key(check, module: str, seed, calls) -> str:
    payloads = [c.payload() for c in calls]
    what = (check.name, module, seed, check.exact_inputs, payloads)
    return hashlib.sha256(_fingerprint() + _digest(what)).hexdigest()


def compute(check, module: str, seed=None) -> Expected:
    """:func:`compute_fresh`, read from the folder of ``AUTOGRADER_ORACLE_CACHE`` when it was kept there
    before (and kept there when not); without the variable, :func:`compute_fresh` itself."""
    folder = os.environ.get(CACHE_VARIABLE, "").strip()
    if not folder:
        return compute_fresh(check, module, seed)
    calls = check.calls(seed)
    path = Path(folder) / f"{_cache_key(check, module, seed, calls)}.pickle"
    try:
        return pickle.loads(path.read_bytes())
    except (OSError, EOFError, pickle.UnpicklingError):
        pass
    found = compute_fresh(check, module, seed, calls)
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, suffix=".partial", delete=False) as handle:
        pickle.dump(found, handle, protocol=4)
    os.replace(handle.name, path)  # whole or absent: another process may be reading it
    return found


def compute_fresh(check, module: str, seed=None, calls=None) -> Expected:
    """Calls, reference outputs and known mistakes of ``check`` (from ``checks/<module>.py``).

    A known mistake's output is kept only where it is finite and the same mistake gives the same
    output (:data:`autograder.rounding.STABLE_RTOL`) on the inputs moved by a few units in the last
    place (:func:`autograder.rounding.stable`; not moved for a check whose inputs are exact by
    design, ``Check.exact_inputs``): one that turns on rounding would differ between machines.
    Raises :class:`ReferenceFailed` when the reference fails on an input. ``calls``: those of
    ``check.calls(seed)`` when already at hand.
    """
    calls = check.calls(seed) if calls is None else calls
    reference = reference_outcomes(calls)
    known = _mistake_catalogue(module).get(check.name)
    if known is None:
        return Expected(calls, reference, [{} for _ in calls])
    mistakes = [_mistakes_of(known, call, outcome) for call, outcome in zip(calls, reference)]
    if check.exact_inputs:
        return Expected(calls, reference, [stable(first, first) for first in mistakes])
    # only a call with a known mistake's output needs the moved inputs (stable keeps the others as they
    # are): the reference is not run again on a large call whose slips are not worked out (a 20,000-variable
    # chain, the 112-camera bundle)
    slipping = [k for k, first in enumerate(mistakes) if any(first.values())]
    moved = [moved_call(calls[k]) for k in slipping]
    again = dict(zip(slipping, (_mistakes_of(known, call, outcome)
                                for call, outcome in zip(moved, reference_outcomes(moved)))))
    return Expected(calls, reference, [stable(first, again.get(k, {})) for k, first in enumerate(mistakes)])


def render() -> dict:
    """``{path relative to autograder/: text}`` of the public data of every check module."""
    from autograder.checks import modules

    files = {}
    for name, module in modules():
        public = {check.name: compute(check, name) for check in module.CHECKS}
        files[f"expected/{name}.json"] = dumps(public)
    return files


def release_expected(check=False, directory=None, files=None) -> list:
    """Rewrite the public data under ``autograder/expected/`` and the exercises' import contracts
    (``autograder/imports.json``), or, with ``check``, only compare; returns the stale paths,
    relative to ``autograder/``. ``files``: :func:`render`'s output when it is already at hand
    (rendering runs every check's reference)."""
    from pathlib import Path

    from autograder.allowed_imports import CONTRACT_FILE, contract_text
    from course.core.impl import REPO_ROOT

    base = Path(directory) if directory else Path(__file__).resolve().parent
    files = render() if files is None else files
    # every exercise's ``Allowed imports:`` line, read by the grader where the tree has no solutions/
    files = {**files, CONTRACT_FILE.name: contract_text(REPO_ROOT / "solutions")}
    present = {f"expected/{p.name}" for p in (base / "expected").glob("*.json")}
    stale = sorted(rel for rel, text in files.items()
                   if not (base / rel).is_file() or not same_data((base / rel).read_text(), text))
    stale += sorted(present - set(files))
    if not check and stale:
        (base / "expected").mkdir(exist_ok=True)
        for rel in present - set(files):
            (base / rel).unlink()
        for rel, text in files.items():
            if rel in stale:
                (base / rel).write_text(text)
    return stale
