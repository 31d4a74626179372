"""course.notebook_helpers.common."""
