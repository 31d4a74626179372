"""One BLAS thread in every library numpy and scipy load, whatever was imported first (``course.core.threads``)."""

import os
import subprocess
import sys

import pytest

from course.core.impl import REPO_ROOT

VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "COURSE_BLAS_THREADS")


def thread_counts(imports: str, **env) -> str:
    """The sorted thread counts of every BLAS loaded after ``imports``, in a fresh process with ``env``."""
    clean = {k: v for k, v in os.environ.items() if k not in VARIABLES}
    code = (f"{imports}; import threadpoolctl; "
            "print(sorted({i['num_threads'] for i in threadpoolctl.threadpool_info()}))")
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**clean, **env},
                          cwd=REPO_ROOT, check=True).stdout.strip()


@pytest.mark.parametrize("imports", [
    "import course, numpy, scipy.linalg",
    "import numpy, course, scipy.linalg",  # scipy's OpenBLAS loads after the limit was set
    "import numpy, scipy.linalg, course",
])
def test_every_blas_runs_on_one_thread(imports):
    assert thread_counts(imports) == "[1]"


def test_course_blas_threads_sets_another_count():
    assert thread_counts("import numpy, course, scipy.linalg", COURSE_BLAS_THREADS="2") == "[2]"
