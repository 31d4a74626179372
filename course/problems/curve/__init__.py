"""course.problems.curve.problem."""
