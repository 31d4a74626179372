"""SO(3) ``Exp``, ``Log``, the skew matrix and the right Jacobian for the framework's chapter-5
code (the VIO problem, its analytic IMU Jacobians, the window, the GTSAM peer).

They are the formulas chapter 5's exercise gives its students (``imu_preintegration.so3_exp``,
``so3_log``, ``skew``, ``right_jacobian``: given, not graded), taken from the reference where
this tree has it and from the exercise file in a student tree, where the given functions are
the same text.
"""

try:
    from solutions.imu_preintegration import right_jacobian, skew, so3_exp, so3_log
except ImportError:  # a student tree: no solutions/
    from exercises.imu_preintegration import right_jacobian, skew, so3_exp, so3_log

__all__ = ["right_jacobian", "skew", "so3_exp", "so3_log"]
