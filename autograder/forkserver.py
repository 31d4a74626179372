"""The fork server: a process that has imported numpy, scipy and the framework once and forks a
fresh child for every check, so that a check does not pay the half second of a new interpreter
and its imports (nor the tens of milliseconds of importing ``course``'s modules again).

Started by :class:`autograder.sandbox.Session` as ``python -I -B -c "<bootstrap>"`` (as the
grader's own user: root when isolating), before any student code exists in the run. It never
imports the student's code, the reference or the expected data: a child inherits only what a
fresh child would import anyway. Protocol on its stdin and stdout (the grader's pipes), one
request at a time: a 4-byte length and a pickle (written by the grader: trusted) of

    {"argv": [CALLS, OUT, PROGRESS], "cwd": str, "env": dict, "uid": int | None,
     "gid": int | None, "stdout": path, "stderr": path, "token": bytes}

answered by the child's pid as ASCII and a newline (``0`` when the fork failed). The child is
forked twice so that it is re-parented to the grader (a subreaper), which waits for it, kills
its process group and reads its exit status as for a ``subprocess.Popen`` child. In the child,
before :func:`autograder.child.main` runs: a new session, the token on stdin, stdout and stderr
to the given files, every other descriptor closed, the working directory and environment of
the check, and (when isolating) the check's uid and gid with no supplementary groups.
"""

import os
import pickle
import struct
import sys

PRELOAD = ("numpy", "scipy.sparse", "scipy.sparse.linalg", "scipy.linalg")
#: the framework's packages whose modules a check's child may import (the exercises stand on
#: core, geometry and solver; the framework tasks on problems), preloaded with all their modules
FRAMEWORK = ("course.core", "course.geometry", "course.solver", "course.problems", "autograder.tasks")


def _read_exactly(fd: int, size: int) -> bytes:
    data = b""
    while len(data) < size:
        chunk = os.read(fd, size - len(data))
        if not chunk:
            return b""
        data += chunk
    return data


def _become_child(request: dict) -> None:
    """Turn this forked process into the check's child; never returns."""
    code = 1
    try:
        os.setsid()
        flags = os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NOFOLLOW
        out = os.open(request["stdout"], flags, 0o600)
        err = os.open(request["stderr"], flags, 0o600)
        read_end, write_end = os.pipe()
        os.write(write_end, request["token"])
        os.close(write_end)
        os.dup2(read_end, 0)
        os.dup2(out, 1)
        os.dup2(err, 2)
        os.closerange(3, os.sysconf("SC_OPEN_MAX"))
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        import tempfile

        tempfile.tempdir = None  # TMPDIR is the check's own
        if request["uid"] is not None:
            os.setgroups([])
            os.setresgid(request["gid"], request["gid"], request["gid"])
            os.setresuid(request["uid"], request["uid"], request["uid"])
        sys.argv = ["-c", *request["argv"]]  # as a child started with ``python -c`` sees it
        from autograder.child import main

        code = main(request["argv"])
        sys.stdout.flush()
        sys.stderr.flush()
    except BaseException:  # noqa: BLE001 - reported on the check's stderr, then exit
        import traceback

        try:
            traceback.print_exc()
            sys.stderr.flush()
        except BaseException:  # noqa: BLE001
            pass
    finally:
        os._exit(code)


def prefer(sites) -> None:
    """Put the entries of ``sys.path`` under ``sites`` (the packages staged where the children can
    read them) before the others, the first entry (the staged framework) staying first: this
    server imports as the grader, who can read the original packages, but its children, forked
    later as another uid, must find every module they import afterwards in the staged copy."""
    staged = [p for p in sys.path if any(p == s or p.startswith(s.rstrip(os.sep) + os.sep) for s in sites)]
    rest = [p for p in sys.path if p not in staged]
    sys.path[:] = rest[:1] + staged + rest[1:]


def preload_framework() -> None:
    """Import every module of :data:`FRAMEWORK` (from the staged copy); a module that fails to
    import is left for the child, which reports it where it matters."""
    import importlib
    import pkgutil

    for package_name in FRAMEWORK:
        try:
            package = importlib.import_module(package_name)
            for module in pkgutil.walk_packages(package.__path__, package_name + "."):
                importlib.import_module(module.name)
        except Exception:  # noqa: BLE001, S112 - the child imports it again and says what is wrong
            continue


def serve(sites=()) -> None:
    """Answer requests until the grader closes the pipe (``sites``: see :func:`prefer`)."""
    prefer(sites)
    requests, replies = os.dup(0), os.dup(1)
    null = os.open(os.devnull, os.O_RDWR)
    os.dup2(null, 0)
    os.dup2(null, 1)
    os.close(null)
    import importlib

    for name in PRELOAD:
        importlib.import_module(name)
    import autograder.child  # noqa: F401 - preloaded for the children

    preload_framework()

    while True:
        header = _read_exactly(requests, 4)
        if not header:
            return
        (size,) = struct.unpack("!I", header)
        request = pickle.loads(_read_exactly(requests, size))  # from the grader: trusted
        pid_read, pid_write = os.pipe()
        sys.stdout.flush()
        sys.stderr.flush()
        try:
            middle = os.fork()
        except OSError:
            os.close(pid_read)
            os.close(pid_write)
            os.write(replies, b"0\n")
            continue
        if middle == 0:  # the intermediate: forks the child and exits, orphaning it to the grader
            os.close(pid_read)
            child = 0
            try:
                child = os.fork()
                if child == 0:
                    os.close(pid_write)
                    _become_child(request)
            except OSError:
                child = 0
            finally:
                os.write(pid_write, str(child).encode())
                os._exit(0)
        os.close(pid_write)
        answer = b""
        while chunk := os.read(pid_read, 32):  # the intermediate writes the pid, then exits
            answer += chunk
        os.close(pid_read)
        os.waitpid(middle, 0)  # gone: the child now belongs to the grader
        del request
        os.write(replies, (answer or b"0") + b"\n")


class ForkServer:
    """The grader's end: ``spawn(request) -> pid or None`` (thread-safe), ``close()``."""

    def __init__(self, python: str, bootstrap: str, env: dict, cwd: str):
        import subprocess
        import threading

        self._lock = threading.Lock()
        # the server's own errors (an import that failed) are shown only with AUTOGRADER_DEBUG set
        stderr = None if os.environ.get("AUTOGRADER_DEBUG") else subprocess.DEVNULL
        self._proc = subprocess.Popen([python, "-I", "-B", "-c", bootstrap], stdin=subprocess.PIPE,
                                      stdout=subprocess.PIPE, stderr=stderr, env=env, cwd=cwd, start_new_session=True)
        self.broken = False

    def spawn(self, request: dict) -> int | None:
        """Fork a child for ``request``; None when the server cannot (the caller starts one itself)."""
        payload = pickle.dumps(request)
        with self._lock:
            if self.broken:
                return None
            try:
                assert self._proc.stdin is not None and self._proc.stdout is not None
                self._proc.stdin.write(struct.pack("!I", len(payload)) + payload)
                self._proc.stdin.flush()
                line = self._proc.stdout.readline()
                pid = int(line.strip() or b"0")
            except (OSError, ValueError):
                pid = 0
            if pid <= 0:
                self.broken = True
                return None
            return pid

    @property
    def alive(self) -> bool:
        """False once it failed to fork or exited: start another."""
        return not self.broken and self._proc.poll() is None

    def close(self) -> None:
        """Stop the server at once (it may still be importing; no child of it is running)."""
        self._proc.kill()
        self._proc.wait()
        for stream in (self._proc.stdin, self._proc.stdout):
            if stream is not None:
                stream.close()


class Forked:
    """A child forked by the server and re-parented to this process: the part of
    ``subprocess.Popen`` the sandbox uses (``pid``, ``returncode``, ``wait(timeout)``)."""

    def __init__(self, pid: int):
        self.pid, self.returncode = pid, None

    def wait(self, timeout=None):
        import subprocess
        import time

        if self.returncode is not None:
            return self.returncode
        deadline = None if timeout is None else time.monotonic() + timeout
        delay = 0.0005
        while True:
            try:
                pid, status = os.waitpid(self.pid, os.WNOHANG)
            except ChildProcessError:  # not ours after all: nothing to read
                self.returncode = -1
                return self.returncode
            if pid:
                self.returncode = os.waitstatus_to_exitcode(status)
                return self.returncode
            if deadline is not None and time.monotonic() >= deadline:
                raise subprocess.TimeoutExpired(str(self.pid), timeout)
            time.sleep(delay)
            delay = min(delay * 2, 0.005)


if __name__ == "__main__":  # pragma: no cover - started by the sandbox with -c
    serve()
