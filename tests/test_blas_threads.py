"""One BLAS thread in every library numpy and scipy load, whatever was imported first (``course.core.threads``)."""

import os
import subprocess
import sys

import pytest

from course.core.impl import REPO_ROOT

THREADS = "import threadpoolctl; print(sorted({i['num_threads'] for i in threadpoolctl.threadpool_info()}))"


@pytest.mark.parametrize("imports", [
    "import course, numpy, scipy.linalg",
    "import numpy, course, scipy.linalg",  # scipy's OpenBLAS loads after the limit was set
    "import numpy, scipy.linalg, course",
])
def test_every_blas_runs_on_one_thread(imports):
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                             "MKL_NUM_THREADS", "COURSE_BLAS_THREADS")}
    out = subprocess.run([sys.executable, "-c", f"{imports}; {THREADS}"], capture_output=True, text=True,
                         env=env, cwd=REPO_ROOT, check=True).stdout
    assert out.strip() == "[1]", imports


def test_course_blas_threads_sets_another_count():
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                             "MKL_NUM_THREADS")}
    env["COURSE_BLAS_THREADS"] = "2"
    out = subprocess.run([sys.executable, "-c", f"import numpy, course, scipy.linalg; {THREADS}"],
                         capture_output=True, text=True, env=env, cwd=REPO_ROOT, check=True).stdout
    assert out.strip() == "[2]"
