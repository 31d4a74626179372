"""SO(3) ``Exp`` and ``Log`` for the framework's chapter-5 code (the VIO problem, the window, the
GTSAM peer).

They are the formulas chapter 5's exercise gives its students (``imu_preintegration.so3_exp``,
``so3_log``: given, not graded), taken from the reference where this tree has it and from the
exercise file in a student tree, where the given functions are the same text.
"""

try:
    from solutions.imu_preintegration import so3_exp, so3_log
except ImportError:  # a student tree: no solutions/
    from exercises.imu_preintegration import so3_exp, so3_log

__all__ = ["so3_exp", "so3_log"]
