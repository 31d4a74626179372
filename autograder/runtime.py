"""What the grading sessions of one process share: the children's copy of the framework, of
Python and its packages where the children's uid cannot read them, and the fork server.

Building these costs about a second of CPU (copying ``course/``, hard-linking the standard
library and the packages, the fork server importing numpy, scipy and the framework). A process
that grades many times (a class, ``make check`` on every exercise, the test suite) builds them
once: :func:`acquire` hands each :class:`autograder.sandbox.Session` the current
:class:`Runtime` and builds a new one when a framework file has changed since (the old one is
removed when its last session ends); everything is removed when the process exits.

A process that ends without running its exit handlers (killed, or ended by ``os._exit``) leaves
its staged folder behind: the process holds a lock on a file of its folder (:data:`LOCK`), which the
kernel frees when it ends, and staging a new folder first removes those in the same temporary
directory whose lock is free (:func:`sweep`).

Sharing gives a student's code nothing it did not have: the copies are root-owned and
read-only to the children, the fork server runs as the grader and never imports student code,
and each session still has its own implementations, uids, working directories and memory watch.
"""

import atexit
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

from autograder import forkserver, isolation

#: the fork server's command: ``python -I -B -c SERVER_BOOTSTRAP`` (root: the staged framework)
SERVER_BOOTSTRAP = (
    "import os, sys; sys.path.insert(0, {root!r}); import site; "
    "[site.addsitedir(p) for p in {sites!r}]; from autograder.forkserver import serve; serve({sites!r}); os._exit(0)"
)
PREFIX = "autograder-runtime-"
#: the file of a staged folder its process holds a lock on (``flock``) while it lives: the kernel frees the lock
#: when the process ends, however it ends
LOCK = "owner.lock"
#: a folder without a lock file is left alone this long (seconds): it may be being staged
UNLOCKED_AGE = 24 * 3600


class Runtime:
    """The staged framework (``root``), the interpreter the children run (``python``, with
    ``env`` and the package directories ``sites``) and the fork server, for isolated children
    (``isolate``) or children that run as the grader's own user."""

    def __init__(self, isolate: bool, repo_root: Path, fingerprint: list):
        self.isolate = isolate
        self.fingerprint = fingerprint  # isolation.framework_files() when it was built
        self.users = 0
        self.python = sys.executable
        self.sites: list = []
        self.env: dict = {}
        self.root = str(repo_root)
        self.base: Path | None = None
        self._lock_file = None  # held while the staged folder is in use (:func:`sweep`)
        self._server: forkserver.ForkServer | None = None
        self._server_lock = threading.Lock()
        if isolate:
            try:
                self._stage()
            except BaseException:
                self.close()
                raise

    def _stage(self) -> None:
        interpreter, packages = isolation.python_problems()
        temp = isolation.temp_root()
        sweep(temp)
        self.base = Path(tempfile.mkdtemp(prefix=PREFIX, dir=temp))
        os.chmod(self.base, 0o755)
        self._lock_file = _hold_lock(self.base)
        isolation.stage_framework(self.base / "stage")
        self.root = str(self.base / "stage")
        if interpreter or packages:
            runtime = isolation.stage_runtime(self.base / "python")
            self.python, self.env = runtime["executable"], runtime["env"]
            self.sites = isolation.site_packages()
            problem = isolation.unreachable(self.python, execute=True)
            if problem:
                raise isolation.IsolationError(
                    f"this Python cannot be run by other users ({'; '.join(interpreter)}) and copying it "
                    f"did not help ({problem}). " + isolation.install_hint())
        if packages:  # e.g. a venv in a 0700 folder: its packages, linked where the children can read them
            self.sites = isolation.stage_site_packages(self.sites, self.base / "packages")
            unreadable = [why for why in map(isolation.unreachable, self.sites) if why]
            if unreadable:
                raise isolation.IsolationError(
                    "the children would run as an unprivileged user who cannot import this Python's packages ("
                    + "; ".join((packages + unreadable)[:3]) + "). " + isolation.install_hint())

    def server(self, env: dict, cwd: str) -> forkserver.ForkServer:
        """The fork server, started on first use (and again if it broke) with ``env`` and ``cwd``."""
        with self._server_lock:
            if self._server is not None and not self._server.alive:
                self._server.close()
                self._server = None
            if self._server is None:
                bootstrap = SERVER_BOOTSTRAP.format(root=self.root, sites=list(self.sites))
                self._server = forkserver.ForkServer(self.python, bootstrap, env, cwd)
            return self._server

    def close(self) -> None:
        with self._server_lock:
            if self._server is not None:
                self._server.close()
                self._server = None
        if self.base is not None:
            isolation.remove_tree(self.base)
            self.base = None
        if self._lock_file is not None:
            self._lock_file.close()
            self._lock_file = None


_lock = threading.Lock()
_current: dict = {}  # isolate -> Runtime
_retired: list = []  # stale runtimes some session still uses


def acquire(isolate: bool, repo_root: Path) -> Runtime:
    """The current runtime for ``isolate`` (built now if there is none or a framework file
    changed); give it back with :func:`release`."""
    with _lock:
        files = isolation.framework_files()
        runtime = _current.get(isolate)
        if runtime is not None and runtime.fingerprint != files:
            del _current[isolate]
            _retire(runtime)
            runtime = None
        if runtime is None:
            runtime = _current[isolate] = Runtime(isolate, repo_root, files)
        runtime.users += 1
        return runtime


def release(runtime: Runtime) -> None:
    with _lock:
        runtime.users -= 1
        if runtime in _retired and runtime.users == 0:
            _retired.remove(runtime)
            runtime.close()


def _retire(runtime: Runtime) -> None:
    if runtime.users == 0:
        runtime.close()
    else:
        _retired.append(runtime)


@atexit.register
def close_all() -> None:
    """Stop every fork server and remove every staged copy (at exit; also for tests)."""
    with _lock:
        for runtime in list(_current.values()) + _retired:
            runtime.close()
        _current.clear()
        _retired.clear()


# ---------------------------------------------------------------- folders left by ended processes


def _hold_lock(base: Path):
    """An open file holding the lock on ``base``'s :data:`LOCK`, taken before the file has that name (a sweep
    never finds it free). POSIX only: a runtime is staged where the children are isolated (Linux, as root)."""
    import fcntl

    partial = base / (LOCK + ".partial")
    handle = open(partial, "w")
    fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    os.replace(partial, base / LOCK)
    return handle


def _remove_if_abandoned(folder: str, age: float) -> bool:
    """Remove ``folder`` (its age in seconds) if its process has ended: its lock is free, or it has no lock file
    and is older than :data:`UNLOCKED_AGE`. The lock is held while removing (two sweeps never both do)."""
    import fcntl

    try:
        handle = open(Path(folder) / LOCK)
    except FileNotFoundError:
        if age <= UNLOCKED_AGE:
            return False  # being staged, or removed meanwhile
        isolation.remove_tree(folder)
        return True
    with handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return False  # its process lives
        isolation.remove_tree(folder)
        return True


def sweep(temp: str) -> list:
    """Remove this user's staged folders in ``temp`` whose process has ended without removing them; return their
    paths."""
    removed = []
    with os.scandir(temp) as entries:
        for entry in entries:
            try:
                if not entry.name.startswith(PREFIX) or not entry.is_dir(follow_symlinks=False):
                    continue
                st = entry.stat(follow_symlinks=False)
                if st.st_uid == os.geteuid() and _remove_if_abandoned(entry.path, time.time() - st.st_mtime):
                    removed.append(entry.path)
            except OSError:
                continue  # removed meanwhile
    return removed
