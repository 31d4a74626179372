"""course.backends.posegraph."""
