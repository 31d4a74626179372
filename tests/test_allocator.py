"""``course.core.allocator``: freed memory stays in the process, so temporaries are not page-faulted
again at every call (glibc only; elsewhere it does nothing)."""

import subprocess
import sys
import textwrap

import pytest

from course.core import allocator

WORK = textwrap.dedent("""
    import resource, sys
    import numpy as np
    if sys.argv[1] == "keep":
        from course.core.allocator import keep_freed_memory
        assert keep_freed_memory()
    def work():  # the temporaries of a 3D linearization: a few MB each, freed on return
        a, b, d = np.ones((6000, 144)), np.ones((6000, 78)), np.ones(260000)
        return a.sum() + b.sum() + d.sum()
    work()
    start = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    for _ in range(10):
        work()
    print((resource.getrusage(resource.RUSAGE_SELF).ru_minflt - start) / 10)
""")


def _faults_per_call(mode):
    done = subprocess.run([sys.executable, "-c", WORK, mode], capture_output=True, text=True, check=True)
    return float(done.stdout)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mallopt is glibc's (Linux)")
def test_kept_memory_is_not_page_faulted_again():
    assert allocator.keep_freed_memory()  # course.app calls it; a second call is harmless
    # 13 MB of temporaries per call: about 3300 pages; glibc's defaults fault part of them again
    assert _faults_per_call("keep") < 20
    assert _faults_per_call("default") > 100


def test_elsewhere_it_does_nothing(monkeypatch):
    monkeypatch.setattr(allocator, "_done", False)
    monkeypatch.setattr(allocator.sys, "platform", "darwin")
    assert allocator.keep_freed_memory() is False
