"""course.backends.bal."""
