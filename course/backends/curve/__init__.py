"""course.backends.curve."""
