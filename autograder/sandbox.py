"""Run calls in a child process under a wall-clock time limit and a memory limit.

The child (:mod:`autograder.child`) is untrusted once the student's code is loaded.
A grading run opens one :class:`Session`; as root, each of its worker slots has a uid of
its own and the child cannot read the reference nor write anything the parent reads or
imports (:mod:`autograder.isolation`); not as root, the children run as the current user
under the same limits and the session's ``notice`` says so.

The parent reads the child's files only as regular files of bounded size (opened with
``O_NOFOLLOW | O_NONBLOCK``, checked with ``fstat``): its output file with
``numpy.load(..., allow_pickle=False)`` after checking the declared sizes, accepting
only float arrays and strings, and only when it carries the token the parent gave the
child on stdin. What the child prints goes to files the child cannot reach by name; it
is kept as text (control characters escaped) to quote in feedback, never parsed. After
each check every process of the child's uid is killed (as root), or its process group.
"""

import io
import os
import pickle
import queue
import re
import secrets
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
import unicodedata
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autograder import forkserver, isolation, runtime
from autograder.records import ErrorInfo, Outcome
from course.core.jit import NO_JIT

REPO_ROOT = Path(__file__).resolve().parent.parent
DEFAULT_TIMEOUT = 10.0
DEFAULT_MEMORY_MB = 2048
#: cap on what the child may write (output file, captured prints)
FILE_BYTES = 64 * 2**20
#: cap on the arrays read back
MAX_OUTPUT_BYTES = 64 * 2**20
PRINTED_BYTES = 4096

BOOTSTRAP = (
    "import os, sys; sys.path.insert(0, {root!r}); import site; "
    "[site.addsitedir(p) for p in {sites!r}]; from autograder.child import main; "
    "code = main(sys.argv[1:]); sys.stdout.flush(); sys.stderr.flush(); os._exit(code)"
)
THREAD_VARIABLES = (
    "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "BLIS_NUM_THREADS",
)
#: environment variables an isolated child keeps (nothing else of the grader's)
KEPT_VARIABLES = ("PATH", "LANG", "LANGUAGE", "LC_ALL", "LC_CTYPE", "TZ", "COURSE_DATA")
_KEY = re.compile(r"^c(\d+)\.(kind|error|modified|f\.([A-Za-z0-9_]+))$")
NOT_ROOT_NOTICE = ("the children run as the current user (no isolation beyond the time, memory and "
                   "file-size limits) because the grader is not root")


@dataclass
class ChildRun:
    """Outcomes per call, what the child printed, and how it ended."""

    outcomes: list
    printed: str = ""
    seconds: float = 0.0
    status: str = "ok"  # ok | timeout | crashed
    running: int = -1  # index of the call in progress when it hung or died
    returncode: int | None = None
    by_budget: bool = False  # timed out because the run's time budget ran out, not the check's limit


def child_env() -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    for name in THREAD_VARIABLES + (NO_JIT,):
        env[name] = "1"
    return env


def isolated_env(work, extra=None) -> dict:
    """The environment of an isolated child: a few variables, none of the grader's secrets."""
    env = {k: os.environ[k] for k in KEPT_VARIABLES if k in os.environ}
    env.setdefault("PATH", "/usr/local/bin:/usr/bin:/bin")
    for name in THREAD_VARIABLES + (NO_JIT,):
        env[name] = "1"
    env.update({"HOME": str(work), "TMPDIR": str(work), "MPLCONFIGDIR": str(work)})
    env.update(extra or {})
    return env


_BIDI = {0x202A, 0x202B, 0x202C, 0x202D, 0x202E, 0x2066, 0x2067, 0x2068, 0x2069}


def escape(text: str) -> str:
    """``text`` with control characters (but newline and tab) and bidi overrides escaped."""
    if text.isprintable():
        return text
    out = []
    for char in text:
        code = ord(char)
        if char in "\n\t" or (unicodedata.category(char) != "Cc" and code not in _BIDI):
            out.append(char)
        elif code < 0x100:
            out.append(f"\\x{code:02x}")
        else:
            out.append(f"\\u{code:04x}")
    return "".join(out)


def run(impl: str, calls: list, timeout=DEFAULT_TIMEOUT, memory_mb=DEFAULT_MEMORY_MB) -> ChildRun:
    """Run ``calls`` (``autograder.checks.Call``) with the implementation ``impl`` in a child
    (a one-check :class:`Session`)."""
    with Session(impl, timeout=timeout, memory_mb=memory_mb, workers=1) as session:
        return session.run(calls)


class Session:
    """One grading run's children: ``with Session(impl, ...) as s: s.run(calls)``.

    ``run`` may be called from ``workers`` threads at once. ``notice`` is a line for the
    user, printed once (e.g. why the children run as the grader's own user), or ''.
    ``budget``: total seconds for the run; once spent, ``run`` starts no child and
    reports a timeout. ``isolate``: None (as root: yes), True or False.

    As root, entering the session makes the reference unreadable by other users, stages the
    implementation into a fresh directory, takes one uid per worker and starts the memory
    watch; it raises :class:`autograder.isolation.IsolationError` with what to do when the
    children could not run safely (it never falls back to root). The staged framework, Python
    and packages and the fork server are the process's (:mod:`autograder.runtime`), shared
    with its other sessions.
    """

    def __init__(self, impl: str, *, timeout=DEFAULT_TIMEOUT, memory_mb=DEFAULT_MEMORY_MB, workers=2,
                 budget=None, isolate=None):
        self.impl, self.timeout, self.memory_mb, self.workers = str(impl), timeout, memory_mb, max(1, workers)
        self.budget = budget
        self.isolate = isolation.is_root() if isolate is None else bool(isolate)
        self.notice = ""
        self._start = None
        self._base = None
        self._slots: list = []
        self._free: queue.Queue = queue.Queue()
        self._watch = None
        self._was_subreaper: bool | None = None
        self._runtime: runtime.Runtime | None = None
        self._child_impl = self.impl
        self._server: forkserver.ForkServer | None = None
        self._prepared: dict = {}
        self._staging = threading.Lock()

    # ------------------------------------------------------------ set-up and tear-down

    def __enter__(self):
        self._start = time.monotonic()
        try:
            if self.isolate:
                self._set_up()
            else:
                self.notice = NOT_ROOT_NOTICE
                self._runtime = runtime.acquire(False, REPO_ROOT)
            self._start_server()
        except BaseException:
            self._tear_down()
            raise
        return self

    def _start_server(self) -> None:
        """The fork server, on Linux where this process can adopt the children it forks
        (``AUTOGRADER_FORKSERVER=0``: a new interpreter per check, as elsewhere)."""
        if not sys.platform.startswith("linux") or os.environ.get("AUTOGRADER_FORKSERVER", "1") == "0":
            return
        if not self.isolate:
            self._was_subreaper = isolation.set_subreaper(True)
            if not isolation.is_subreaper():
                return
        assert self._runtime is not None
        if self.isolate:
            assert self._runtime.base is not None
            env, cwd = isolated_env(self._runtime.base, self._runtime.env), str(self._runtime.base)
        else:
            env, cwd = child_env(), tempfile.gettempdir()
        self._server = self._runtime.server(env, cwd)

    def __exit__(self, *exc):
        self._tear_down()
        return False

    def _set_up(self):
        if not isolation.is_root():
            raise isolation.IsolationError("isolating the children needs root")
        said = []
        changed = isolation.protect_reference()
        if changed:
            names = ", ".join(_relative(path) for path in changed)
            said.append(f"made the reference unreadable by other users (chmod go-rwx): {names}")
        self._runtime = runtime.acquire(True, REPO_ROOT)
        self._base = Path(tempfile.mkdtemp(prefix="autograder-", dir=isolation.temp_root()))
        os.chmod(self._base, 0o711)
        self._child_impl = isolation.stage_impl(self.impl, self._base)
        self._prepared[self.impl] = self._child_impl
        self._slots = isolation.acquire_slots(self.workers)
        for slot in self._slots:
            home = self._base / f"slot-{slot.uid}"
            home.mkdir(mode=0o711)
            os.chmod(home, 0o711)
            (home / "out").mkdir(mode=0o700)
            slot.home = home
            self._free.put(slot)
        self._was_subreaper = isolation.set_subreaper(True)
        self._watch = isolation.MemoryWatch(self._slots)
        self._watch.start()
        self.notice = "; ".join(said)

    def _tear_down(self):
        self._server = None  # the runtime's, shared: it stays for the next session
        if self._watch is not None:
            self._watch.stop()
            self._watch = None
        for slot in self._slots:
            isolation.kill_uid(slot.uid, slot.gid)
            isolation.sweep_temp(slot.uid)
            slot.release()
        self._slots = []
        if self._was_subreaper is False:
            isolation.set_subreaper(False)
        self._was_subreaper = None
        if self._base is not None:
            isolation.remove_tree(self._base)
            self._base = None
        if self._runtime is not None:
            runtime.release(self._runtime)
            self._runtime = None

    def prepare(self, impl: str) -> str:
        """Make another implementation gradable in this session (staged for the children when
        isolating); returns what :meth:`run` takes as ``impl``."""
        impl = str(impl)
        with self._staging:
            if impl not in self._prepared:
                self._prepared[impl] = isolation.stage_impl(impl, self._base) \
                    if self.isolate and self._base is not None else impl
            return self._prepared[impl]

    # ------------------------------------------------------------ one check

    def run(self, calls: list, timeout=None, impl=None) -> ChildRun:
        """Run ``calls`` in a fresh child, with the session's implementation or ``impl`` (from
        :meth:`prepare`); blocks while all worker slots are busy."""
        timeout = timeout or self.timeout
        by_budget = False
        if self.budget is not None and self._start is not None:
            remaining = self.budget - (time.monotonic() - self._start)
            if remaining <= 0.05:
                error = ErrorInfo("Timeout", f"the grading time budget of {self.budget:g} s ran out "
                                             "before this check could run")
                spent = _all_failed(calls, -1, error, "", 0.0, "timeout", None)
                spent.by_budget = True
                return spent
            if remaining < timeout:
                timeout, by_budget = remaining, True
        if not self.isolate:
            with tempfile.TemporaryDirectory(prefix="autograder-", ignore_cleanup_errors=True) as name:
                tmp = Path(name)
                work = tmp / "work"
                work.mkdir()
                return self._execute(calls, timeout, by_budget, tmp, work, None, impl)
        slot = self._free.get()
        marks = isolation.temp_marks()
        try:
            work = slot.home / "work"
            isolation.remove_tree(work)
            work.mkdir(mode=0o700)
            os.chown(work, slot.uid, slot.gid)
            os.chmod(work, 0o700)
            try:
                return self._execute(calls, timeout, by_budget, slot.home, work, slot, impl)
            except BaseException:  # _execute kills the uid's processes itself when it returns
                isolation.kill_uid(slot.uid, slot.gid)
                raise
            finally:
                isolation.remove_tree(work)
                isolation.sweep_temp(slot.uid, unchanged=marks)
        finally:
            self._free.put(slot)

    def _execute(self, calls, timeout, by_budget, home: Path, work: Path, slot, impl=None) -> ChildRun:
        start = time.perf_counter()
        token = secrets.token_hex(16)
        calls_path, out_path, progress_path = home / "calls.pkl", work / "out.npz", work / "progress"
        self._write_spec(calls, timeout, calls_path, slot, impl or self._child_impl)
        streams = home / "out" if slot is not None else home
        if slot is not None:
            slot.memory_exceeded = False
            slot.memory_limit = int(self.memory_mb * 2**20) if self.memory_mb else None
        status, proc = "ok", None
        try:
            try:
                proc = self._spawn(token, [str(calls_path), str(out_path), str(progress_path)], work, streams, slot)
            except OSError as exc:
                error = ErrorInfo("Crash", f"the grader could not start the child process ({exc}): "
                                           "tell your instructor")
                return _all_failed(calls, -1, error, "", time.perf_counter() - start, "crashed", None)
            isolation.TRACKED.add(proc.pid)
            try:
                proc.wait(timeout=timeout)
            except subprocess.TimeoutExpired:
                status = "timeout"
            finally:
                if slot is not None:
                    slot.memory_limit = None
                _kill_group(proc)
                if slot is not None:
                    isolation.kill_uid(slot.uid, slot.gid)
                proc.wait()
                isolation.TRACKED.discard(proc.pid)
        finally:
            if slot is not None:
                slot.memory_limit = None
        return self._outcome(calls, proc, status, by_budget, timeout, streams, out_path, progress_path, token, slot,
                             time.perf_counter() - start)

    def _write_spec(self, calls, timeout, calls_path: Path, slot, impl: str) -> None:
        """The child's instructions (a pickle only the grader and the child's group can read)."""
        spec = {
            "impl": impl,
            "calls": [call.payload() for call in calls],
            "memory_bytes": int(self.memory_mb * 2**20) if self.memory_mb else None,
            "cpu_seconds": timeout + 1,
            "file_bytes": FILE_BYTES,
            "token_stdin": True,
            "processes": isolation.PROCESSES if slot is not None else None,
            "kill_others": slot is not None,
        }
        fd = os.open(calls_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW, 0o600)
        with os.fdopen(fd, "wb") as f:
            pickle.dump(spec, f)
        if slot is not None:
            os.chown(calls_path, 0, slot.gid)
            os.chmod(calls_path, 0o640)

    def _spawn(self, token: str, argv: list, work: Path, streams: Path, slot):
        """The check's child, forked by the fork server where there is one, else a new interpreter;
        either way in a session of its own, as the slot's uid when isolating, with the token on stdin."""
        assert self._runtime is not None
        env = isolated_env(work, self._runtime.env) if slot is not None else child_env()
        if self._server is not None:
            pid = self._server.spawn({
                "argv": argv, "cwd": str(work), "env": env, "stdout": str(streams / "stdout"),
                "stderr": str(streams / "stderr"), "token": token.encode(),
                "uid": slot.uid if slot is not None else None, "gid": slot.gid if slot is not None else None})
            if pid is not None:
                return forkserver.Forked(pid)
        assert self._runtime is not None
        root, python, sites = self._runtime.root, self._runtime.python, self._runtime.sites
        command = [python, "-I", "-B", "-c", BOOTSTRAP.format(root=root, sites=list(sites)), *argv]
        options: dict = {"env": env}
        if slot is not None:
            options.update({"user": slot.uid, "group": slot.gid, "extra_groups": []})
        with open(streams / "stdout", "wb") as out, open(streams / "stderr", "wb") as err:
            proc = subprocess.Popen(command, cwd=work, stdin=subprocess.PIPE, stdout=out, stderr=err,
                                    start_new_session=True, **options)
        try:
            assert proc.stdin is not None  # started with stdin=PIPE
            proc.stdin.write(token.encode())
            proc.stdin.close()
        except OSError:
            pass
        return proc

    def _outcome(self, calls, proc, status, by_budget, timeout, streams, out_path, progress_path, token, slot,
                 seconds) -> ChildRun:
        """What the child left: its outputs, or why there are none (memory, time, a crash)."""
        printed = _printed(streams / "stdout", streams / "stderr")
        owner = slot.uid if slot is not None else None
        running = _progress(progress_path, owner)
        if slot is not None and slot.memory_exceeded:
            error = ErrorInfo("MemoryError", f"its processes together used more than the memory limit of "
                                             f"{self.memory_mb:g} MiB and were stopped")
            return _all_failed(calls, running, error, printed, seconds, "crashed", proc.returncode)
        if status == "timeout":
            if by_budget:
                message = (f"the grading time budget of {self.budget:g} s ran out while this check ran "
                           f"(after {timeout:.3g} s)")
            else:
                message = (f"did not finish within the time limit of {timeout:g} s: "
                           "an infinite loop, or a very slow computation?")
            timed_out = _all_failed(calls, running, ErrorInfo("Timeout", message), printed, seconds, status,
                                    proc.returncode)
            timed_out.by_budget = by_budget
            return timed_out
        outcomes, problem = _read(out_path, len(calls), token=token, owner=owner)
        if outcomes is None:
            return _all_failed(calls, running, ErrorInfo("Crash", _crash_message(proc.returncode, problem)), printed,
                               seconds, "crashed", proc.returncode)
        return ChildRun(outcomes, printed, seconds, "ok", returncode=proc.returncode)


def _crash_message(code, problem: str) -> str:
    """Why a child left no result, from its exit status."""
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
    return message

def _relative(path) -> str:
    try:
        text = str(Path(path).relative_to(REPO_ROOT))
    except ValueError:
        text = str(path)
    return text + ("/" if Path(path).is_dir() else "")


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


def read_regular(path, limit, cap=None, owner=None):
    """``(bytes, problem)``: up to ``limit`` bytes of ``path`` when it is a regular file
    (not a symlink, FIFO or device) of at most ``cap`` bytes, owned by ``owner`` when
    given; ``(None, why)`` otherwise. Never blocks on a FIFO."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        return None, ""
    except OSError as exc:
        return None, f"its output could not be opened ({errno_name(exc)})"
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            return None, "its output is not a regular file"
        if owner is not None and st.st_uid != owner:
            return None, "its output file belongs to another user"
        if cap is not None and st.st_size > cap:
            return None, f"its output file has {st.st_size} bytes"
        chunks, total = [], 0
        while total < limit:
            chunk = os.read(fd, min(1 << 20, limit - total))
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
        return b"".join(chunks), ""
    except OSError as exc:
        return None, f"its output could not be read ({errno_name(exc)})"
    finally:
        os.close(fd)


def errno_name(exc) -> str:
    import errno

    return errno.errorcode.get(exc.errno, type(exc).__name__) if exc.errno else type(exc).__name__


def _progress(path, owner=None) -> int:
    data, _ = read_regular(path, 20, cap=64, owner=owner)
    if not data:
        return -1
    text = data.decode("ascii", "replace")
    return int(text) if text.isdigit() else -1


def _printed(*paths) -> str:
    parts = []
    for path in paths:
        data, _ = read_regular(path, PRINTED_BYTES)
        if data:
            parts.append(escape(data.decode("utf-8", "replace")))
    return "\n".join(part.rstrip("\n") for part in parts)


def _read(path, count, token=None, owner=None):
    """Outcomes from the child's npz, or ``(None, reason)``; untrusted input.

    With ``token``, the file must carry it (key ``token``); with ``owner``, belong to
    that uid.
    """
    raw, problem = read_regular(path, MAX_OUTPUT_BYTES + 1, cap=MAX_OUTPUT_BYTES, owner=owner)
    if raw is None:
        return None, problem
    try:
        with zipfile.ZipFile(io.BytesIO(raw)) as archive:
            total = sum(info.file_size for info in archive.infolist())
        if total > MAX_OUTPUT_BYTES:
            return None, f"its output file declares {total} bytes"
        outcomes = [Outcome() for _ in range(count)]
        seen = set()
        with np.load(io.BytesIO(raw), allow_pickle=False) as data:
            if token is not None:
                if "token" not in data.files:
                    return None, "its output file was not written by the grader's child"
                mark = data["token"]
                if mark.dtype.kind != "U" or mark.ndim != 0 or str(mark) != token:
                    return None, "its output file was not written by the grader's child"
            for key in data.files:
                match = _KEY.match(key)
                if not match or int(match.group(1)) >= count:
                    continue
                index = int(match.group(1))
                value = data[key]
                if match.group(2) == "modified":
                    if value.dtype.kind == "U" and value.ndim == 1 and value.size <= 64:
                        outcomes[index].modified = tuple(escape(str(part)[:200]) for part in value)
                    continue
                seen.add(index)
                if match.group(2) == "kind" and value.dtype.kind == "U" and value.ndim == 0:
                    outcomes[index].kind = escape(str(value)[:100])
                elif match.group(2) == "error" and value.dtype.kind == "U" and value.shape == (3,):
                    outcomes[index].error = ErrorInfo(*(escape(str(part)[:2000]) for part in value))
                elif match.group(3) and value.dtype == np.float64:
                    outcomes[index].fields[match.group(3)] = value
        for index in range(count):
            if index not in seen:
                outcomes[index].error = ErrorInfo("Crash", "no result was returned for this call")
        return outcomes, ""
    except Exception as exc:  # noqa: BLE001 - a corrupt or forged file
        return None, f"unreadable output file: {type(exc).__name__}"
