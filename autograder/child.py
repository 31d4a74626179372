"""The code that runs in the child process, next to the student's code.

Started by :mod:`autograder.sandbox` as
``python -I -B -c "<bootstrap>" CALLS OUT PROGRESS`` with a fresh process group.
It sets its resource limits before numpy loads, reads the calls (a pickle written by
the parent), loads the implementation with ``course.impl.load``, runs each call and
writes every output as named float arrays (errors as strings) to ``OUT`` with
``numpy.savez``; the parent reads that file with ``allow_pickle=False``. Before each
call it writes the call's index to ``PROGRESS`` so that the parent can name the call
that hung or crashed. Nothing printed here is ever parsed.

Key scheme of ``OUT``: ``c{i}.kind`` (str), ``c{i}.f.{name}`` (float array) for each
output field, ``c{i}.error`` (str array: kind, message, where).
"""

import os
import sys


def set_limits(memory_bytes: int, cpu_seconds: float, file_bytes: int) -> None:
    import resource

    for limit, value in (
        (resource.RLIMIT_AS, memory_bytes),
        (resource.RLIMIT_CPU, int(cpu_seconds) + 1),
        (resource.RLIMIT_FSIZE, file_bytes),
        (resource.RLIMIT_CORE, 0),
    ):
        if value is None:
            continue
        soft, hard = resource.getrlimit(limit)
        value = value if hard == resource.RLIM_INFINITY else min(value, hard)
        resource.setrlimit(limit, (value, hard))


def to_fields(value):
    """``(kind, {name: float array})`` for a call's output; raises TypeError otherwise.

    Tuples give fields ``"0", "1", ...``; dataclasses their field names; dicts their
    keys; an array, list or scalar the single field ``"value"``.
    """
    import dataclasses

    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        names = [f.name for f in dataclasses.fields(value)]
        return f"dataclass:{type(value).__name__}", {n: _as_float(getattr(value, n), n) for n in names}
    if isinstance(value, tuple):
        return f"tuple:{len(value)}", {str(k): _as_float(v, f"element {k}") for k, v in enumerate(value)}
    if isinstance(value, dict):
        return "dict", {str(k): _as_float(v, str(k)) for k, v in value.items()}
    return "value", {"value": _as_float(value, "the value")}


def _as_float(value, what):
    import numpy as np

    if value is None or isinstance(value, (str, bytes)):
        raise TypeError(f"{what} is {type(value).__name__} {value!r:.40}, expected a number or an array")
    try:
        arr = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise TypeError(f"{what} ({type(value).__name__}) is not an array of numbers: {exc}") from None
    if arr.dtype.kind not in "biuf":
        raise TypeError(
            f"{what} ({type(value).__name__}) has dtype {arr.dtype}, expected numbers"
            + (" (complex values)" if arr.dtype.kind == "c" else "")
        )
    return np.array(arr, dtype=np.float64)


def _location(tb, roots) -> str:
    """The innermost traceback frame inside the student's files, as 'line N of file: code'."""
    import linecache
    import traceback

    frames = traceback.extract_tb(tb)
    for frame in reversed(frames):
        path = os.path.realpath(frame.filename)
        if any(path.startswith(root + os.sep) for root in roots):
            line = (frame.line or linecache.getline(frame.filename, frame.lineno)).strip()
            return f"line {frame.lineno} of {os.path.basename(path)}: {line}"
    for frame in reversed(frames):
        if not frame.filename.startswith("<"):
            return f"line {frame.lineno} of {os.path.basename(frame.filename)} ({frame.name})"
    return ""


def _error(exc, roots):
    kind = type(exc).__name__
    try:
        if isinstance(exc, SystemExit):
            message = f"called sys.exit({exc.code!r})"
        elif isinstance(exc, MemoryError):
            message = str(exc) or "out of memory"
        else:
            message = str(exc)
        where = "" if isinstance(exc, SyntaxError) else _location(exc.__traceback__, roots)
    except BaseException:  # noqa: BLE001 - an exception class with a broken __str__
        message, where = "(the exception could not be printed)", ""
    return [kind, message[:2000], where]


def resolve(impl, target: str, init: dict):
    """The callable named by ``target`` (see ``autograder.checks.Call``)."""
    import functools
    import importlib

    if target.startswith("@"):
        module, _, name = target[1:].partition(":")
        return functools.partial(getattr(importlib.import_module(module), name), impl=impl)
    module, _, qualname = target.partition(":")
    obj = impl.module(module)
    parts = qualname.split(".")
    for k, part in enumerate(parts):
        obj = getattr(obj, part)
        if isinstance(obj, type) and k < len(parts) - 1:
            obj = obj(**init)
    return obj


def run_calls(impl, calls, roots=(), progress=None):
    """Run ``calls`` (payload dicts) with ``impl``; ``[(kind, fields) or error list]``.

    Each call gets its own copy of the inputs, so a function that modifies its
    arguments in place cannot change the inputs of the next call.
    """
    import copy

    results = []
    for index, call in enumerate(calls):
        if progress is not None:
            progress(index)
        try:
            args, kwargs = copy.deepcopy((tuple(call.get("args", ())), dict(call.get("kwargs") or {})))
            function = resolve(impl, call["target"], call.get("init") or {})
            value = function(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - anything the student's code does
            results.append(_error(exc, roots))
            continue
        try:
            results.append(to_fields(value))
        except BaseException as exc:  # noqa: BLE001
            results.append(["OutputError", f"returned {type(value).__name__}: {exc}"[:2000], ""])
    return results


def main(argv) -> int:
    calls_path, out_path, progress_path = argv
    import pickle

    with open(calls_path, "rb") as f:
        spec = pickle.load(f)  # written by the parent (trusted); unpickled before student code runs
    set_limits(spec["memory_bytes"], spec["cpu_seconds"], spec["file_bytes"])
    import numpy as np

    savez, replace, write = np.savez, os.replace, os.write

    def progress(index):
        fd = os.open(progress_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        try:
            write(fd, str(index).encode())
        finally:
            os.close(fd)

    calls = spec["calls"]
    name = str(spec["impl"])
    root = name if os.sep in name else os.path.join(os.path.dirname(os.path.dirname(__file__)), name)
    roots = [os.path.realpath(root)]
    try:
        from course import impl as impl_loader

        impl = impl_loader.load(spec["impl"])
        results = run_calls(impl, calls, roots, progress)
    except BaseException as exc:  # noqa: BLE001 - e.g. a syntax error in the student's package
        error = _error(exc, roots)
        error[:2] = ["ImportFailure", f"could not import your implementation: {error[0]}: {error[1]}"]
        results = [error for _ in calls]

    arrays = {}
    for index, result in enumerate(results):
        if isinstance(result, tuple):
            kind, fields = result
            arrays[f"c{index}.kind"] = np.array(kind)
            for name, value in fields.items():
                arrays[f"c{index}.f.{name}"] = value
        else:
            arrays[f"c{index}.error"] = np.array([str(part) for part in result])
    tmp = out_path + ".tmp"
    with open(tmp, "wb") as f:
        savez(f, **arrays)
    replace(tmp, out_path)
    return 0


if __name__ == "__main__":  # pragma: no cover - the sandbox uses a bootstrap snippet
    sys.exit(main(sys.argv[1:]))
