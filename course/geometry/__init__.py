"""course.geometry.se2."""
