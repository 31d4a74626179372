"""Keep freed memory in the process, so numpy's temporaries are not page-faulted at every call.

glibc's ``malloc`` returns memory to the system eagerly: blocks above a threshold that adapts
(128 KB at first) are mapped afresh at each allocation, and the top of the heap is trimmed once
128 KB or more of it is free. A linearization that allocates a few megabytes of temporaries
then pays a page fault per 4 KB page on every call: half of a Gauss-Newton linearization of
parking-garage (16 ms of which 8 are page faults, this machine). :func:`keep_freed_memory` sets
the two thresholds once (``mallopt``): blocks up to 32 MB (glibc's largest mapping threshold)
come from the heap, and up to 256 MB of free heap is kept. The peak memory is unchanged; memory
freed stays with the process. Where the C library is not glibc (macOS, Windows, musl) it does
nothing. Compiled peers measured in the same process allocate through the same ``malloc``.
"""

import ctypes
import sys

#: ``mallopt`` parameters (glibc's malloc.h)
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
#: blocks up to this size come from the heap (glibc refuses more)
MMAP_THRESHOLD = 32 << 20
#: free heap kept before it is returned to the system
TRIM_THRESHOLD = 256 << 20

_done = False


def keep_freed_memory() -> bool:
    """Set glibc's thresholds (once per process); ``True`` where they were set."""
    global _done
    if _done:
        return True
    if not sys.platform.startswith("linux"):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):  # not glibc
        return False
    _done = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return _done
