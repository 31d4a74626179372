"""Course framework: the numerical core of SLAM back ends.

Students write the pieces in ``exercises/``; this package owns everything else:
problems, the minimizer loops, traces, datasets, peer back ends and the CLI.
"""

__version__ = "0.1.0"

from course.core.threads import limit_blas_threads

limit_blas_threads()


def __getattr__(name):
    """``course.check_jacobian`` (``course.geometry.jacobian_check``), imported when first used:
    ``import course`` stays cheap for the command line."""
    if name == "check_jacobian":
        from course.geometry.jacobian_check import check_jacobian

        return check_jacobian
    raise AttributeError(f"module 'course' has no attribute {name!r}")
