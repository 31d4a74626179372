"""The machine a benchmark ran on, written beside its figures, and what differs between two.

:func:`describe` gives a dict (JSON as it is):

- ``cpu``: ``model name`` of ``/proc/cpuinfo`` (else ``platform.processor()``, else the machine type);
  ``simd``: which of :data:`SIMD` its ``flags`` list (a virtual machine's model name is often generic);
- ``cores``: ``os.cpu_count()``; ``affinity``: the cores this process may run on
  (``os.sched_getaffinity``, where the system has it); ``load_average``: 1, 5 and 15 minutes;
- ``blas``: each BLAS/LAPACK (and OpenMP) library loaded by numpy and scipy, as threadpoolctl's
  ``threadpool_info()`` sees it: ``user_api``, ``internal_api`` (openblas, mkl, blis, ...),
  ``prefix`` (the library's name), ``folder`` (the folder of its file: ``numpy.libs``, ``scipy.libs``, or the
  system's), ``version``, ``threading_layer``, ``architecture`` (the kernel OpenBLAS picked: Haswell,
  SkylakeX, ...) and ``num_threads``;
- ``python``, ``platform``; ``versions``: numpy, scipy and the peers (``PACKAGES``) from
  ``importlib.metadata``, ``None`` where one is not installed;
- ``date`` (UTC, ISO 8601), ``commit`` (``git rev-parse HEAD`` of this tree, ``None`` outside git),
  ``dirty`` (tracked files changed since it) and ``command``.

:func:`differences` lists, one line each, the CPU, cores, BLAS libraries and versions that differ
between two descriptions.
"""

import os
import platform
import shlex
import subprocess
import sys
from datetime import datetime, timezone
from importlib import metadata
from pathlib import Path

from course.core.impl import REPO_ROOT

#: where Linux describes the CPU
CPUINFO = "/proc/cpuinfo"
#: the distributions whose versions are recorded: the numerical stack, the peers and our compiled helpers
PACKAGES = ("numpy", "scipy", "gtsam", "g2opy", "pycolmap", "pyceres", "jax", "jaxlib", "numba", "qdldl", "cvxopt",
            "threadpoolctl")
#: the vector instruction sets recorded (``/proc/cpuinfo`` flags): the ones BLAS kernels and numpy dispatch on
SIMD = ("sse4_2", "avx", "avx2", "fma", "avx512f", "avx512bw", "avx512vl", "avx512_vnni", "avx512_bf16", "amx_tile")
#: the fields of each BLAS library kept from threadpoolctl
BLAS_FIELDS = ("user_api", "internal_api", "prefix", "version", "threading_layer", "architecture", "num_threads")


def cpu_model() -> str:
    """The CPU's model name: ``/proc/cpuinfo``'s first ``model name`` (Linux), else
    ``platform.processor()``, else ``platform.machine()``."""
    try:
        with open(CPUINFO, encoding="utf-8", errors="replace") as file:
            for line in file:
                key, _, value = line.partition(":")
                if key.strip() == "model name" and value.strip():
                    return value.strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def simd() -> list | None:
    """The :data:`SIMD` sets the CPU has (``/proc/cpuinfo``'s first ``flags``), ``None`` without that file."""
    try:
        with open(CPUINFO, encoding="utf-8", errors="replace") as file:
            for line in file:
                key, _, value = line.partition(":")
                if key.strip() in ("flags", "Features"):
                    have = set(value.split())
                    return [name for name in SIMD if name in have]
    except OSError:
        pass
    return None


def affinity() -> int | None:
    """How many cores this process may run on (``None`` where the system does not say)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return None


def blas() -> list:
    """The BLAS/LAPACK and OpenMP libraries numpy and scipy loaded, :data:`BLAS_FIELDS` of each."""
    import numpy  # noqa: F401  (loads numpy's BLAS)
    import scipy.linalg  # noqa: F401  (loads scipy's, where it has its own)
    from threadpoolctl import threadpool_info

    return [{**{key: entry.get(key) for key in BLAS_FIELDS},
             "folder": Path(entry["filepath"]).parent.name if entry.get("filepath") else None}
            for entry in threadpool_info()]


def versions(packages=PACKAGES) -> dict:
    """``{distribution: version or None}``."""
    out: dict[str, str | None] = {}
    for name in packages:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def _git(*args: str) -> str | None:
    try:
        done = subprocess.run(["git", "-C", str(REPO_ROOT), *args], capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def commit() -> tuple:
    """``(commit, dirty)`` of this tree: ``(None, None)`` outside a git work tree or without git."""
    head = _git("rev-parse", "HEAD")
    if not head:
        return None, None
    status = _git("status", "--porcelain", "--untracked-files=no")
    return head, None if status is None else bool(status)


def load_average() -> list | None:
    """The 1, 5 and 15 minute load averages (``None`` where the system does not say)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def describe(command: str | None = None) -> dict:
    """This machine and this run (see the module doc); ``command`` defaults to ``sys.argv``."""
    head, dirty = commit()
    return {
        "cpu": cpu_model(),
        "simd": simd(),
        "cores": os.cpu_count(),
        "affinity": affinity(),
        "load_average": load_average(),
        "blas": blas(),
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "platform": platform.platform(),
        "versions": versions(),
        "date": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "commit": head,
        "dirty": dirty,
        "command": command if command is not None else shlex.join(["python", "-m", "course", *sys.argv[1:]]),
    }


def _blas_key(entry: dict) -> str:
    return f"{entry.get('internal_api')} in {entry.get('folder') or entry.get('prefix')}"


def differences(old: dict, new: dict) -> list:
    """One line per difference between two :func:`describe` dicts: CPU, cores, affinity, each BLAS
    library (by its ``internal_api`` and ``folder``: version, kernel, threads; or one of them only
    in one), Python, the platform and each version. Missing fields (an older file) count as ``None``."""
    lines = []
    for key, label in (("cpu", "CPU"), ("simd", "SIMD"), ("cores", "cores"), ("affinity", "affinity (cores usable)"),
                       ("python", "Python"), ("platform", "platform")):
        if old.get(key) != new.get(key):
            lines.append(f"{label}: {old.get(key)} -> {new.get(key)}")
    before = {_blas_key(e): e for e in old.get("blas") or []}
    after = {_blas_key(e): e for e in new.get("blas") or []}
    for key in [*before, *(k for k in after if k not in before)]:
        if key not in after:
            lines.append(f"BLAS {key}: only in the old run")
        elif key not in before:
            lines.append(f"BLAS {key}: only in the new run (version {after[key].get('version')}, "
                         f"kernel {after[key].get('architecture')})")
        else:
            for field, label in (("version", "version"), ("architecture", "kernel"), ("num_threads", "threads")):
                if before[key].get(field) != after[key].get(field):
                    lines.append(f"BLAS {key} {label}: {before[key].get(field)} -> {after[key].get(field)}")
    old_versions, new_versions = old.get("versions") or {}, new.get("versions") or {}
    for name in [*old_versions, *(k for k in new_versions if k not in old_versions)]:
        if old_versions.get(name) != new_versions.get(name):
            lines.append(f"{name}: {old_versions.get(name) or 'not installed'} -> "
                         f"{new_versions.get(name) or 'not installed'}")
    return lines
