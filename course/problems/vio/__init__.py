"""course.problems.vio.problem."""
