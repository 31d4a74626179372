"""course.backends.vio."""
