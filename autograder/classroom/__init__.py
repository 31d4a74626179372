"""Grading a whole class: the submissions read (``intake``), graded in one run (``batch``),
recorded (``gradebook``), joined across machines (``merge``) and summed up (``report``)."""
