"""The public checks' inputs and answers, shipped as data (``autograder/expected/*.json``).

For every public check the release step (:mod:`autograder.oracle`, on the instructor's
side) records the calls the child makes, the reference's outputs of those calls, and the
outputs of each known mistake that feedback names. Grading a public check reads this
file; it never imports the reference. One JSON file per exercise module::

    {"format": 1, "checks": {"<check name>": {"calls": [...], "reference": [...],
                                              "mistakes": [...]}}}

Values are plain JSON with tagged objects for what JSON lacks, decoded without running
any code from the file: ``{"__array__": dtype, "shape": [...], "data": [...]}`` (floats
written by ``repr``, so they round-trip exactly; NaN and infinities as Python's json
writes them), ``{"__tuple__": [...]}`` and ``{"__state__": {"lam": ..., "nu": ...}}``
(a ``course.solver.damping.DampingState``).
"""

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autograder.records import Call, Outcome

FORMAT = 1
DIRECTORY = Path(__file__).resolve().parent / "expected"
_DTYPES = ("float64", "int64", "bool")


class ExpectedDataError(RuntimeError):
    """The shipped data is missing, stale or malformed."""


#: keys of the per-call data that hold the reference's intermediate factors, not known mistakes
FACTOR_PREFIX = "factor: "


@dataclass
class Expected:
    """What the judge of one check compares with: calls, reference outputs, mistakes."""

    calls: list  # Call
    reference: list  # Outcome per call
    mistakes: list  # per call: {key: [(value, why), ...]}; keys ``FACTOR_PREFIX + name``: reference factors

    def without_catalogue(self) -> "Expected":
        """The same, as if no mistake were known: the reference's factors stay (held-out feedback)."""
        kept = [{key: pairs for key, pairs in per_call.items() if key.startswith(FACTOR_PREFIX)}
                for per_call in self.mistakes]
        return Expected(self.calls, self.reference, kept)


# ---------------------------------------------------------------- values


def encode(value):
    """A JSON-ready form of the inputs and outputs a check uses."""
    from course.solver.damping import DampingState

    if isinstance(value, np.ndarray) or isinstance(value, np.generic):
        arr = np.asarray(value)
        dtype = {"f": "float64", "i": "int64", "u": "int64", "b": "bool"}.get(arr.dtype.kind)
        if dtype is None:
            raise TypeError(f"cannot store an array of dtype {arr.dtype}")
        data = arr.astype(dtype).ravel().tolist()
        return {"__array__": dtype, "shape": list(arr.shape), "data": data}
    if isinstance(value, DampingState):
        return {"__state__": {"lam": float(value.lam), "nu": float(value.nu)}}
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError(f"dict keys must be strings: {list(value)[:5]}")
        return {k: encode(v) for k, v in value.items()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    raise TypeError(f"cannot store {type(value).__name__}")


def decode(value):
    if isinstance(value, list):
        return [decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "__array__" in value:
        dtype = value["__array__"]
        if dtype not in _DTYPES:
            raise ExpectedDataError(f"unknown dtype {dtype!r}")
        return np.array(value["data"], dtype=dtype).reshape(value["shape"])
    if "__tuple__" in value:
        return tuple(decode(v) for v in value["__tuple__"])
    if "__state__" in value:
        from course.solver.damping import DampingState

        return DampingState(lam=float(value["__state__"]["lam"]), nu=float(value["__state__"]["nu"]))
    return {k: decode(v) for k, v in value.items()}


# ---------------------------------------------------------------- records


def _encode_call(call: Call) -> dict:
    returns = {"__tuple__": list(call.returns)} if isinstance(call.returns, tuple) else call.returns
    return {"target": call.target, "args": encode(tuple(call.args)), "kwargs": encode(dict(call.kwargs)),
            "init": encode(dict(call.init)), "returns": returns, "where": call.where, "label": call.label,
            "groups": {text: [int(k) for k in rows] for text, rows in call.groups.items()}}


def _decode_call(data: dict) -> Call:
    returns = data["returns"]
    if isinstance(returns, dict):
        returns = tuple(returns["__tuple__"])
    groups = {text: tuple(rows) for text, rows in data.get("groups", {}).items()}
    return Call(data["target"], decode(data["args"]), decode(data["kwargs"]), decode(data["init"]),
                returns, data["where"], data["label"], groups)


def encode_expected(expected: Expected) -> dict:
    return {
        "calls": [_encode_call(c) for c in expected.calls],
        "reference": [{"kind": o.kind, "fields": encode(dict(o.fields))} for o in expected.reference],
        "mistakes": [{key: [[encode(np.asarray(v, dtype=float)), why] for v, why in known]
                      for key, known in per_call.items()} for per_call in expected.mistakes],
    }


def decode_expected(data: dict) -> Expected:
    calls = [_decode_call(c) for c in data["calls"]]
    reference = [Outcome(fields=decode(o["fields"]), kind=o["kind"]) for o in data["reference"]]
    mistakes = [{key: [(decode(v), why) for v, why in known] for key, known in per_call.items()}
                for per_call in data["mistakes"]]
    if not len(calls) == len(reference) == len(mistakes):
        raise ExpectedDataError("calls, reference outputs and mistakes differ in number")
    return Expected(calls, reference, mistakes)


# ---------------------------------------------------------------- files


def path_for(module: str, directory: Path = DIRECTORY) -> Path:
    return Path(directory) / f"{module}.json"


def dumps(checks: dict) -> str:
    """The file text for ``{check name: Expected}`` (stable, so that staleness is a text diff)."""
    body = {"format": FORMAT, "checks": {name: encode_expected(e) for name, e in checks.items()}}
    return json.dumps(body, sort_keys=True, separators=(",", ":")) + "\n"


def load(module: str, directory: Path = DIRECTORY) -> dict:
    """``{check name: Expected}`` of one check module's public checks."""
    path = path_for(module, directory)
    try:
        body = json.loads(path.read_text())
    except FileNotFoundError:
        raise ExpectedDataError(f"{path} is missing: run `python -m course release` (instructor)") from None
    except (OSError, ValueError) as exc:
        raise ExpectedDataError(f"{path}: unreadable ({exc})") from None
    if body.get("format") != FORMAT:
        raise ExpectedDataError(f"{path}: format {body.get('format')!r}, expected {FORMAT}")
    try:
        return {name: decode_expected(data) for name, data in body["checks"].items()}
    except (KeyError, TypeError, ValueError) as exc:
        raise ExpectedDataError(f"{path}: malformed ({type(exc).__name__}: {exc})") from None


#: how closely two renderings must agree on a known mistake's output, relative to its largest entry:
#: the feedback matches a student's output to a mistake at about this tolerance, so a mistake that
#: another machine rounds differently below it is the same mistake
MISTAKE_RTOL = 1e-6


def same_data(text_a: str, text_b: str, rtol: float = 1e-9, atol: float = 1e-12) -> bool:
    """Whether two renderings of the expected data agree: the same structure, strings and
    integers, and floats within ``rtol``/``atol``. Another numpy or CPU may round the last digit
    of a reference output differently (``exp`` by another SIMD path); that is not stale data.

    An array's entries are compared at the scale of the array, ``|a - b| <= rtol max|b| + atol``
    (``max|b|`` over its finite entries): a solve's rounding error is relative to its largest entry,
    so its smallest entries may move by far more than ``rtol`` of themselves when another BLAS, or
    another order of the same sums, computes them. A float outside an array is compared at its own
    scale, ``|a - b| <= rtol |b| + atol``. A known mistake's arrays (under ``"mistakes"``) agree
    within :data:`MISTAKE_RTOL` of their largest entry."""

    def close(a, b, tolerance, relative) -> bool:
        # np.isclose's test, in plain floats (a million numpy scalar calls took 20 s)
        if a == b or (a != a and b != b):
            return True
        return math.isfinite(a) and math.isfinite(b) and abs(a - b) <= tolerance + relative * abs(b)

    def same_array(a: dict, b: dict, mistake: bool) -> bool:
        data_a, data_b = a.get("data"), b.get("data")
        if a.keys() != b.keys() or any(a[k] != b[k] for k in a if k != "data") or not isinstance(data_a, list) \
                or not isinstance(data_b, list) or len(data_a) != len(data_b):
            return a == b
        if a["__array__"] != "float64" or any(isinstance(x, bool) or not isinstance(x, (int, float))
                                              for x in (*data_a, *data_b)):
            return data_a == data_b  # integers and booleans: exact
        scale = max((abs(x) for x in data_b if math.isfinite(x)), default=0.0)
        tolerance = MISTAKE_RTOL * scale if mistake else rtol * scale + atol
        return all(close(x, y, tolerance, 0.0) for x, y in zip(data_a, data_b))

    def same(a, b, mistake=False) -> bool:
        if isinstance(a, dict):
            if not isinstance(b, dict) or a.keys() != b.keys():
                return False
            if "__array__" in a:
                return same_array(a, b, mistake)
            return all(same(a[k], b[k], mistake or k == "mistakes") for k in a)
        if isinstance(a, list):
            return isinstance(b, list) and len(a) == len(b) and all(same(x, y, mistake) for x, y in zip(a, b))
        if isinstance(a, float) or isinstance(b, float):
            if not isinstance(a, (int, float)) or not isinstance(b, (int, float)) or isinstance(a, bool) \
                    or isinstance(b, bool):
                return False
            return close(a, b, atol, rtol)
        return type(a) is type(b) and a == b

    return text_a == text_b or same(json.loads(text_a), json.loads(text_b))
