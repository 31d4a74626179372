"""course.release.stubs."""
