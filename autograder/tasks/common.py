"""What several tasks share: errors, strings as numbers, stubs, and a run as numbers."""

import threading
from typing import Any

import numpy as np

from course.solver import StopReason


class OutputError(Exception):
    """The student's code returned something the framework cannot use (reported as is)."""


def exclusive() -> bool:
    """True when no other Python thread runs (the child): module state may be patched."""
    return threading.active_count() == 1


def encode_text(text, limit=60) -> np.ndarray:
    """A string as float character codes (the child returns numbers only)."""
    return np.array([float(ord(c)) for c in str(text)[:limit]], dtype=float)


def decode_text(codes) -> str:
    return "".join(chr(int(c)) for c in np.asarray(codes, dtype=float).ravel() if 0 <= c < 0x110000)


def encode_lists(lists, what="lists") -> np.ndarray:
    """A list of lists of numbers as one flat float array (the child returns arrays only): their number, then
    each list's length and entries; ``[[a, b], [], [c]]`` is ``(3, 2, a, b, 0, 1, c)``. OutputError naming
    ``what[k]`` for an entry that is not a list of numbers."""
    out = [float(len(lists))]
    for k, items in enumerate(lists):
        try:
            entries = np.asarray(items, dtype=float).ravel()
        except (TypeError, ValueError) as exc:
            raise OutputError(f"{what}[{k}] is not a list of numbers: {exc}") from None
        out.append(float(len(entries)))
        out.extend(entries.tolist())
    return np.array(out, dtype=float)


def decode_lists(flat) -> list:
    """The lists of :func:`encode_lists`' array, entries as ints where they are whole numbers."""
    flat = np.asarray(flat, dtype=float).ravel().tolist()
    lists, at = [], 1
    for _ in range(int(flat[0])):
        size = int(flat[at])
        lists.append([int(x) if float(x).is_integer() else x for x in flat[at + 1:at + 1 + size]])
        at += 1 + size
    return lists


def stub_todo(call) -> str:
    """The NotImplementedError message of ``call()`` when it is an unwritten stub, else ''.

    Used when a constructor is a stub, to also name the stub of a method that could not
    be reached (so that every TODO is listed); any other outcome says nothing.
    """
    try:
        call()
    except NotImplementedError as exc:
        return str(exc)
    except Exception:  # noqa: BLE001 - a written method on a bare instance may fail anyhow
        return ""
    return ""


def stop_code(reason) -> float:
    """Why a run stopped as a number: the position of ``reason`` in :class:`StopReason`, -1 if none."""
    reasons = list(StopReason)
    return float(reasons.index(reason)) if reason in reasons else -1.0


def stop_reason(code) -> str:
    """The :class:`StopReason` value of a :func:`stop_code` ('?' for -1 or an unknown code)."""
    reasons = list(StopReason)
    code = int(code)
    return reasons[code].value if 0 <= code < len(reasons) else "?"


def run_summary(result) -> dict:
    """A run as numbers: where it ended, and how rejected steps were retried."""
    trace = result.trace
    rejected = [k for k in range(1, len(trace)) if not trace[k].accepted]
    refactorized = [k for k in rejected
                    if k + 1 < len(trace) and trace[k + 1].factorizations != trace[k].factorizations]
    trailing = 0
    for record in reversed(trace[1:]):
        if record.accepted:
            break
        trailing += 1
    return {
        "params": np.asarray(result.params, float).ravel(),
        "final_chi2": float(result.final_chi2),
        "iterations": float(result.iterations),
        "factorizations": float(result.factorizations),
        "rejected": float(len(rejected)),
        "refactorized_after_rejection": float(len(refactorized)),
        "trailing_rejections": float(trailing),
        "stop": stop_code(result.stop_reason),
    }


def assemble_each(assembler, blocks, information) -> dict:
    """``assembler.assemble(e, A, B, information)`` for each ``(e, A, B)`` of ``blocks``, on one
    pattern (the sparse assemblers of chapters 2 and 6).

    Fields per call k: ``H{k}`` (dense copy of the returned matrix), ``b{k}``, ``chi2{k}``,
    ``csc{k}``; and ``diagonal_ok`` (1 when ``diagonal_positions`` points at the diagonal of
    ``H.data``, 0 when it does not, NaN when there is none).
    """
    return each_assembly(assembler, [(np.array(e), np.array(A), np.array(B), np.array(information))
                                     for e, A, B in blocks])


def each_assembly(assembler, arguments) -> dict:
    """``assembler.assemble(*args)`` for each ``args`` of ``arguments``, on one pattern; the fields of
    :func:`assemble_each`."""
    import scipy.sparse as sp

    out: dict = {}
    H: Any = None
    for k, args in enumerate(arguments):
        result = assembler.assemble(*args)
        if not isinstance(result, tuple) or len(result) != 3:
            raise OutputError(f"returned {type(result).__name__}, expected a tuple (H, b, chi2)")
        H, b, chi2 = result
        out[f"H{k}"] = H.toarray() if sp.issparse(H) else np.asarray(H)
        out[f"csc{k}"] = float(sp.issparse(H) and H.format == "csc")
        out[f"b{k}"], out[f"chi2{k}"] = b, chi2
    positions = getattr(assembler, "diagonal_positions", None)
    if positions is None or not (sp.issparse(H) and H.format == "csc"):
        out["diagonal_ok"] = float("nan")
    else:
        try:
            out["diagonal_ok"] = float(np.array_equal(H.data[np.asarray(positions)], H.diagonal()))
        except (IndexError, TypeError, ValueError):
            out["diagonal_ok"] = 0.0
    return out
