"""course.problems.bal.problem."""
