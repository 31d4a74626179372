"""Chapter 8's marginal covariances of any of the course's problems at given values
(``course.marginals.marginals``), through the implementation's ``marginal_covariances``."""

from course.marginals.layouts import GaugeError, Layout, layout_of
from course.marginals.marginals import Marginals, joint_marginal, marginals

__all__ = ["GaugeError", "Layout", "Marginals", "joint_marginal", "layout_of", "marginals"]
