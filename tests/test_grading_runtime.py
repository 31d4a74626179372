"""The runtime the grading sessions of one process share (``autograder.runtime``): built once,
rebuilt when a framework file changes, removed at exit (or, when its process ended without exit
handlers, by the next staging)."""

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from autograder import isolation, runtime, sandbox
from autograder.records import Call

pytestmark = pytest.mark.slow  # real children

CALL = Call("damping:GavinType1.damping_diagonal", args=(np.array([1.0, 2.0, 3.0]), 0.5))


def one_check(isolate):
    with sandbox.Session("solutions", isolate=isolate) as session:
        server = session._server
        result = session.run([CALL])
    assert result.outcomes[0].fields["value"].tolist() == [0.5, 1.0, 1.5]
    return server


@pytest.mark.parametrize("isolate", [False, pytest.param(True, marks=pytest.mark.skipif(
    not isolation.is_root(), reason="isolating the children needs root"))])
def test_sessions_share_one_fork_server_until_the_framework_changes(monkeypatch, isolate):
    runtime.close_all()
    first = one_check(isolate)
    assert one_check(isolate) is first
    if first is None:
        pytest.skip("no fork server here (not Linux, or AUTOGRADER_FORKSERVER=0)")
    files = isolation.framework_files()
    changed = [(path, mtime + 1, size) for path, mtime, size in files]
    monkeypatch.setattr(isolation, "framework_files", lambda: changed)
    second = one_check(isolate)
    assert second is not first and not first.alive
    runtime.close_all()
    assert not second.alive


def test_a_stale_runtime_stays_until_its_last_session_ends(monkeypatch):
    runtime.close_all()
    with sandbox.Session("solutions", isolate=False) as session:
        old = session._runtime
        files = isolation.framework_files()
        monkeypatch.setattr(isolation, "framework_files", lambda: [(p, m + 1, s) for p, m, s in files])
        new = runtime.acquire(False, sandbox.REPO_ROOT)
        assert new is not old
        assert session.run([CALL]).outcomes[0].fields["value"].tolist() == [0.5, 1.0, 1.5]
        runtime.release(new)
    assert old.users == 0
    runtime.close_all()


STAGE_AND_END = ("import os, sys; from autograder import runtime, sandbox; "
                 "print(runtime.acquire(True, sandbox.REPO_ROOT).base, flush=True); "
                 "os._exit(0) if sys.argv[1] == 'exit' else None")


@pytest.fixture
def temp_root(monkeypatch):
    """A temporary directory the children's uid can search, for this test's staged folders."""
    root = Path(tempfile.mkdtemp(prefix="runtime-sweep-"))
    root.chmod(0o755)
    monkeypatch.setenv("TMPDIR", str(root))
    yield root
    isolation.remove_tree(root)


def stage_in_a_child(how: str) -> Path:
    """The folder a child process staged, the child having ended by ``how``: ``exit`` (``os._exit``,
    its exit handlers not run) or ``return``."""
    done = subprocess.run([sys.executable, "-c", STAGE_AND_END, how], cwd=sandbox.REPO_ROOT,
                          capture_output=True, text=True, timeout=120, check=True)
    return Path(done.stdout.strip())


def staged_folder(root: Path, lock: bool = True) -> Path:
    """A folder as staging makes it, in ``root``: with its lock file (``lock``), the lock free."""
    folder = Path(tempfile.mkdtemp(prefix=runtime.PREFIX, dir=root))
    if lock:
        (folder / runtime.LOCK).write_text("")
    return folder


@pytest.mark.skipif(not isolation.is_root(), reason="isolating the children needs root")
def test_a_folder_left_by_a_process_that_ended_without_exit_handlers_goes_at_the_next_staging(temp_root):
    import fcntl

    alive = staged_folder(temp_root)
    with open(alive / runtime.LOCK) as held:  # its process (this one) lives
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        left = stage_in_a_child("exit")
        assert left.parent == temp_root and (left / "stage").is_dir() and (left / runtime.LOCK).is_file()
        stage_in_a_child("return")
        assert sorted(temp_root.iterdir()) == [alive]


def test_the_sweep_removes_only_folders_whose_process_has_ended(tmp_path):
    import fcntl

    alive = staged_folder(tmp_path)
    held = open(alive / runtime.LOCK)  # its process (here, this one) holds the lock
    fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
    ended = staged_folder(tmp_path)  # the lock free: its process has ended
    unlocked = staged_folder(tmp_path, lock=False)  # no lock file yet: being staged
    other = tmp_path / "not-a-runtime"
    other.mkdir()
    try:
        assert runtime.sweep(str(tmp_path)) == [str(ended)]
        assert sorted(tmp_path.iterdir()) == sorted([alive, unlocked, other])
        old = time.time() - runtime.UNLOCKED_AGE - 60
        os.utime(unlocked, (old, old))
        assert runtime.sweep(str(tmp_path)) == [str(unlocked)]
        assert sorted(tmp_path.iterdir()) == sorted([alive, other])
    finally:
        held.close()
    assert runtime.sweep(str(tmp_path)) == [str(alive)]
