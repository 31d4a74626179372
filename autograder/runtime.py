"""What the grading sessions of one process share: the children's copy of the framework, of
Python and its packages where the children's uid cannot read them, and the fork server.

Building these costs about a second of CPU (copying ``course/``, hard-linking the standard
library and the packages, the fork server importing numpy, scipy and the framework). A process
that grades many times (a class, ``make check`` on every exercise, the test suite) builds them
once: :func:`acquire` hands each :class:`autograder.sandbox.Session` the current
:class:`Runtime` and builds a new one when a framework file has changed since (the old one is
removed when its last session ends); everything is removed when the process exits.

Sharing gives a student's code nothing it did not have: the copies are root-owned and
read-only to the children, the fork server runs as the grader and never imports student code,
and each session still has its own implementations, uids, working directories and memory watch.
"""

import atexit
import os
import sys
import tempfile
import threading
from pathlib import Path

from autograder import forkserver, isolation

#: the fork server's command: ``python -I -B -c SERVER_BOOTSTRAP`` (root: the staged framework)
SERVER_BOOTSTRAP = (
    "import os, sys; sys.path.insert(0, {root!r}); import site; "
    "[site.addsitedir(p) for p in {sites!r}]; from autograder.forkserver import serve; serve({sites!r}); os._exit(0)"
)


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
        self.base = Path(tempfile.mkdtemp(prefix="autograder-runtime-", dir=isolation.temp_root()))
        os.chmod(self.base, 0o755)
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
