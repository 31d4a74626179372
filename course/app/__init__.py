"""course.app."""
