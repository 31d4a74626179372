"""The code that runs in the child process, next to the student's code.

Started by :mod:`autograder.sandbox` as
``python -I -B -c "<bootstrap>" CALLS OUT PROGRESS`` with a fresh process group.
It sets its resource limits before numpy loads, reads the calls (a pickle written by
the parent), loads the implementation with ``course.core.impl.load``, runs each call and
writes every output as named float arrays (errors as strings) to ``OUT`` with
``numpy.savez``; the parent reads that file with ``allow_pickle=False``. Before each
call it writes the call's index to ``PROGRESS`` so that the parent can name the call
that hung or crashed. Nothing printed here is ever parsed.

Key scheme of ``OUT``: ``c{i}.kind`` (str), ``c{i}.f.{name}`` (float array) for each
output field, ``c{i}.error`` (str array: kind, message, where), ``c{i}.modified`` (str
array: the arguments the call changed in place), and ``token`` (str: what the parent
wrote to the child's stdin, so that a file the student's code wrote and then exited
is not taken for the child's output).

When the parent isolates the child (a dedicated uid, see :mod:`autograder.isolation`),
the spec says ``kill_others``: before writing ``OUT`` the child kills every other
process of its uid (``kill(-1, SIGKILL)`` as that uid), so nothing the student's code
forked can replace ``OUT`` afterwards; a forked copy of this runner never writes it
(only the original pid does). The student's code runs in this process, so this is a
guard against accidents and simple tricks, not against code that patches the runner.
"""

import os
import sys


def set_limits(memory_bytes: int, cpu_seconds: float, file_bytes: int, processes=None) -> None:
    """Resource limits of this process (and what it forks); ``processes`` is RLIMIT_NPROC,
    which counts every process and thread of the uid: set it only under a dedicated uid."""
    import resource

    for limit, value in (
        (resource.RLIMIT_AS, memory_bytes),
        (resource.RLIMIT_CPU, int(cpu_seconds) + 1),
        (resource.RLIMIT_FSIZE, file_bytes),
        (resource.RLIMIT_CORE, 0),
        (resource.RLIMIT_NPROC, processes),
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
    except Exception as exc:  # noqa: BLE001 - ragged lists and whatever else numpy refuses
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
            line = (frame.line or linecache.getline(frame.filename, frame.lineno or 0)).strip()
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


def _arrays_in(name, value):
    """``[(name, array)]`` of the numpy arrays in an argument: itself, or one level down
    in a tuple, list, dict or dataclass."""
    import dataclasses

    import numpy as np

    if isinstance(value, np.ndarray):
        return [(name, value)]
    found = []
    if isinstance(value, (tuple, list)):
        items = [(f"{name}[{k}]", v) for k, v in enumerate(value)]
    elif isinstance(value, dict):
        items = [(f"{name}[{k!r}]", v) for k, v in value.items()]
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        items = [(f"{name}.{f.name}", getattr(value, f.name, None)) for f in dataclasses.fields(value)]
    else:
        items = []
    for label, item in items:
        if isinstance(item, np.ndarray):
            found.append((label, item))
    return found


def snapshot(function, args, kwargs):
    """Copies of the arrays among the arguments: ``[(name, array, copy)]``.

    Positional arguments are named by the function's signature when it binds, else
    ``argument k`` (counted from 1); keyword arguments by their keyword.
    """
    import inspect

    named = None
    try:
        bound = inspect.signature(function).bind(*args, **kwargs)
        named = []
        for pname, value in bound.arguments.items():
            kind = bound.signature.parameters[pname].kind
            if kind is inspect.Parameter.VAR_POSITIONAL:
                named += [(f"{pname}[{k}]", v) for k, v in enumerate(value)]
            elif kind is inspect.Parameter.VAR_KEYWORD:
                named += list(value.items())
            else:
                named.append((pname, value))
    except (TypeError, ValueError):
        named = None
    if named is None:
        named = [(f"argument {k + 1}", v) for k, v in enumerate(args)] + list(kwargs.items())
    kept = []
    for name, value in named:
        for label, array in _arrays_in(str(name), value):
            kept.append((label, array, array.copy()))
    return kept


def changed(kept) -> tuple:
    """Names in ``kept`` (from :func:`snapshot`) whose array differs from its copy."""
    import numpy as np

    names = []
    for name, array, before in kept:
        try:
            if array.shape != before.shape:
                same = False
            else:
                try:
                    same = bool(np.array_equal(array, before, equal_nan=True))
                except TypeError:  # equal_nan on a dtype without NaN
                    same = bool(np.array_equal(array, before))
        except Exception:  # noqa: BLE001 - an array subclass with odd comparisons
            same = True
        if not same and name not in names:
            names.append(name)
    return tuple(names)


def run_calls(impl, calls, roots=(), progress=None, modified=None):
    """Run ``calls`` (payload dicts) with ``impl``; ``[(kind, fields) or error list]``.

    Each call gets its own copy of the inputs, so a function that modifies its
    arguments in place cannot change the inputs of the next call. When ``modified`` is
    a list, it receives per call the names of the array arguments the call changed in
    place (a tuple, empty when none).
    """
    import copy

    results = []
    for index, call in enumerate(calls):
        if progress is not None:
            progress(index)
        kept = []
        try:
            args, kwargs = copy.deepcopy((tuple(call.get("args", ())), dict(call.get("kwargs") or {})))
            function = resolve(impl, call["target"], call.get("init") or {})
            if modified is not None:
                kept = snapshot(function, args, kwargs)
            value = function(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - anything the student's code does
            results.append(_error(exc, roots))
            if modified is not None:
                modified.append(changed(kept))
            continue
        if modified is not None:
            modified.append(changed(kept))
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
    token = b""
    if spec.get("token_stdin"):  # the parent writes a token to stdin and closes it
        while len(token) < 256:
            chunk = os.read(0, 256)
            if not chunk:
                break
            token += chunk
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.close(null)
    set_limits(spec["memory_bytes"], spec["cpu_seconds"], spec["file_bytes"], spec.get("processes"))
    import signal

    import numpy as np

    savez, replace, write, getpid, kill = np.savez, os.replace, os.write, os.getpid, os.kill
    me = getpid()

    def progress(index):
        if getpid() != me:  # a copy forked by the student's code
            return
        fd = os.open(progress_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
        try:
            write(fd, str(index).encode())
        finally:
            os.close(fd)

    calls = spec["calls"]
    name = str(spec["impl"])
    root = name if os.sep in name else os.path.join(os.path.dirname(os.path.dirname(__file__)), name)
    roots = [os.path.realpath(root)]
    modified: list = []
    try:
        from course.core import impl as impl_loader

        impl = impl_loader.load(spec["impl"])
        results = run_calls(impl, calls, roots, progress, modified)
    except BaseException as exc:  # noqa: BLE001 - e.g. a syntax error in the student's package
        error = _error(exc, roots)
        error[:2] = ["ImportFailure", f"could not import your implementation: {error[0]}: {error[1]}"]
        results = [error for _ in calls]

    if getpid() != me:  # a copy forked by the student's code never writes the output
        os._exit(0)
    if spec.get("kill_others"):  # dedicated uid: nothing the student forked outlives this line
        try:
            kill(-1, signal.SIGKILL)
        except OSError:
            pass
    arrays = {"token": np.array(token.decode("ascii", "replace"))}
    for index, result in enumerate(results):
        if isinstance(result, tuple):
            kind, fields = result
            arrays[f"c{index}.kind"] = np.array(kind)
            for name, value in fields.items():
                arrays[f"c{index}.f.{name}"] = value
        else:
            arrays[f"c{index}.error"] = np.array([str(part) for part in result])
        names = modified[index] if index < len(modified) else ()
        if names:
            arrays[f"c{index}.modified"] = np.array([str(n) for n in names])
    tmp = out_path + ".tmp"
    try:
        os.unlink(tmp)
    except OSError:
        pass
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    with os.fdopen(fd, "wb") as out:
        savez(out, **arrays)  # type: ignore[arg-type]  # the stubs take the names for keywords
    replace(tmp, out_path)
    return 0


if __name__ == "__main__":  # pragma: no cover - the sandbox uses a bootstrap snippet
    sys.exit(main(sys.argv[1:]))
