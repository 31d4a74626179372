"""Course framework: the numerical core of SLAM back ends.

Students write the pieces in ``exercises/``; this package owns everything else:
problems, the minimizer loops, traces, datasets, peer back ends and the CLI.
"""

__version__ = "0.1.0"

from course.core.threads import limit_blas_threads

limit_blas_threads()
