"""Run calls in a child process under a wall-clock time limit and a memory limit.

The child (:mod:`autograder.child`) is untrusted once the student's code is loaded:
its output file is read with ``numpy.load(..., allow_pickle=False)`` after checking
the declared sizes, only float arrays and strings are accepted, and what it prints is
kept as text to quote in feedback, never parsed. On timeout the whole process group
is killed.
"""

import os
import pickle
import re
import signal
import subprocess
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autograder.checks import ErrorInfo, Outcome

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_TIMEOUT = 10.0
DEFAULT_MEMORY_MB = 2048
#: cap on what the child may write (output file, captured prints)
FILE_BYTES = 64 * 2**20
#: cap on the arrays read back
MAX_OUTPUT_BYTES = 64 * 2**20
PRINTED_BYTES = 4096

BOOTSTRAP = (
    "import os, sys; sys.path.insert(0, {root!r}); from autograder.child import main; "
    "code = main(sys.argv[1:]); sys.stdout.flush(); sys.stderr.flush(); os._exit(code)"
)
THREAD_VARIABLES = (
    "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "BLIS_NUM_THREADS",
)
_KEY = re.compile(r"^c(\d+)\.(kind|error|f\.([A-Za-z0-9_]+))$")


@dataclass
class ChildRun:
    """Outcomes per call, what the child printed, and how it ended."""

    outcomes: list
    printed: str = ""
    seconds: float = 0.0
    status: str = "ok"  # ok | timeout | crashed
    running: int = -1  # index of the call in progress when it hung or died
    returncode: int = None


def child_env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    for name in THREAD_VARIABLES:
        env[name] = "1"
    return env


def run(impl: str, calls: list, timeout=DEFAULT_TIMEOUT, memory_mb=DEFAULT_MEMORY_MB) -> ChildRun:
    """Run ``calls`` (``autograder.checks.Call``) with the implementation ``impl`` in a child."""
    start = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="autograder-", ignore_cleanup_errors=True) as tmp:
        tmp = Path(tmp)
        work = tmp / "work"
        work.mkdir()
        calls_path, out_path, progress_path = tmp / "calls.pkl", tmp / "out.npz", tmp / "progress"
        spec = {
            "impl": impl,
            "calls": [call.payload() for call in calls],
            "memory_bytes": int(memory_mb * 2**20) if memory_mb else None,
            "cpu_seconds": timeout + 1,
            "file_bytes": FILE_BYTES,
        }
        with open(calls_path, "wb") as f:
            pickle.dump(spec, f)
        command = [sys.executable, "-I", "-B", "-c", BOOTSTRAP.format(root=str(REPO_ROOT)),
                   str(calls_path), str(out_path), str(progress_path)]
        with open(tmp / "stdout", "wb") as out, open(tmp / "stderr", "wb") as err:
            proc = subprocess.Popen(command, cwd=work, env=child_env(), stdin=subprocess.DEVNULL,
                                    stdout=out, stderr=err, start_new_session=True)
            status = "ok"
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                status = "timeout"
            finally:
                _kill_group(proc)
                proc.wait()
        seconds = time.perf_counter() - start
        printed = _printed(tmp / "stdout", tmp / "stderr")
        running = _progress(progress_path)
        if status == "timeout":
            error = ErrorInfo("Timeout", f"did not finish within the time limit of {timeout:g} s: "
                                         "an infinite loop, or a very slow computation?")
            return _all_failed(calls, running, error, printed, seconds, status, proc.returncode)
        outcomes, problem = _read(out_path, len(calls))
        if outcomes is None:
            code = proc.returncode
            if code is not None and code < 0:
                try:
                    name = signal.Signals(-code).name
                except ValueError:
                    name = str(-code)
                how = f"was killed by signal {name}"
                if -code == signal.SIGXCPU:
                    how += " (CPU time limit)"
                elif -code == signal.SIGXFSZ:
                    how += " (it wrote more than the file size limit, e.g. printing in a loop)"
            else:
                how = f"exited with status {code}"
            message = f"{how} before returning any result"
            if problem:
                message += f" ({problem})"
            if code == 0:
                message += ": does your code call os._exit(), sys.exit() or quit()?"
            elif code is not None and code > 0:
                message += (": does your code call os._exit() or sys.exit()? (if it printed a "
                            "traceback below, the grader could not start: tell your instructor)")
            return _all_failed(calls, running, ErrorInfo("Crash", message), printed, seconds,
                               "crashed", code)
        return ChildRun(outcomes, printed, seconds, "ok", returncode=proc.returncode)


def _kill_group(proc) -> None:
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def _all_failed(calls, running, error, printed, seconds, status, returncode) -> ChildRun:
    outcomes = []
    for index in range(len(calls)):
        if index < running:  # finished, but its result was lost with the process
            outcomes.append(Outcome(error=ErrorInfo("Lost", "its result was lost: " + error.message)))
        else:
            outcomes.append(Outcome(error=ErrorInfo(error.kind, error.message, error.where)))
    return ChildRun(outcomes, printed, seconds, status, running=running, returncode=returncode)


def _progress(path) -> int:
    try:
        text = Path(path).read_text()[:20]
        return int(text) if text.isdigit() else -1
    except (OSError, ValueError):
        return -1


def _printed(*paths) -> str:
    parts = []
    for path in paths:
        try:
            with open(path, "rb") as f:
                data = f.read(PRINTED_BYTES)
        except OSError:
            continue
        if data:
            parts.append(data.decode("utf-8", "replace"))
    return "\n".join(part.rstrip("\n") for part in parts)


def _read(path, count):
    """Outcomes from the child's npz, or ``(None, reason)``; untrusted input."""
    if not Path(path).is_file():
        return None, ""
    try:
        with zipfile.ZipFile(path) as archive:
            total = sum(info.file_size for info in archive.infolist())
        if total > MAX_OUTPUT_BYTES:
            return None, f"its output file declares {total} bytes"
        outcomes = [Outcome() for _ in range(count)]
        seen = set()
        with np.load(path, allow_pickle=False) as data:
            for key in data.files:
                match = _KEY.match(key)
                if not match or int(match.group(1)) >= count:
                    continue
                index = int(match.group(1))
                value = data[key]
                seen.add(index)
                if match.group(2) == "kind" and value.dtype.kind == "U" and value.ndim == 0:
                    outcomes[index].kind = str(value)[:100]
                elif match.group(2) == "error" and value.dtype.kind == "U" and value.shape == (3,):
                    outcomes[index].error = ErrorInfo(*(str(part)[:2000] for part in value))
                elif match.group(3) and value.dtype == np.float64:
                    outcomes[index].fields[match.group(3)] = value
        for index in range(count):
            if index not in seen:
                outcomes[index].error = ErrorInfo("Crash", "no result was returned for this call")
        return outcomes, ""
    except Exception as exc:  # noqa: BLE001 - a corrupt or forged file
        return None, f"unreadable output file: {type(exc).__name__}"
