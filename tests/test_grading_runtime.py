"""The runtime the grading sessions of one process share (``autograder.runtime``): built once,
rebuilt when a framework file changes, removed at exit."""

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
