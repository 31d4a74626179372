"""What several tasks share: errors, strings as numbers, stubs, and a run as numbers."""

import threading

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
