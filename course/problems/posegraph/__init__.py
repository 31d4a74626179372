"""course.problems.posegraph.problem."""
