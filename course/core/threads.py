"""One BLAS thread for every solver in this package, ours and the peers'.

Every peer here runs on one thread (g2o's Eigen solver, Ceres with num_threads=1,
GTSAM's default), so ours does too: a fair comparison. It also avoids a trap of
shared 2-core machines: OpenBLAS splits dot products of more than ~10^4 entries over
threads, and when the other core is busy one such product stalls for milliseconds.
Set ``COURSE_BLAS_THREADS`` to another number to change this.
"""

import os
import sys

_VARIABLES = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def limit_blas_threads() -> None:
    """Every BLAS of this process on ``COURSE_BLAS_THREADS`` threads (1 by default), and its children's.

    numpy and scipy each load an OpenBLAS of their own, numpy's at its import and scipy's at the import of
    ``scipy.linalg``; an OpenBLAS reads its thread count from the environment when it loads. So the variables
    are set first (a library loaded later reads them: scipy's, when numpy was imported before this package),
    then the libraries loaded already are limited in place."""
    count = os.environ.get("COURSE_BLAS_THREADS", "1")
    for name in _VARIABLES:
        os.environ.setdefault(name, count)
    if "numpy" not in sys.modules:
        return
    from threadpoolctl import threadpool_limits

    threadpool_limits(int(count), user_api="blas")
