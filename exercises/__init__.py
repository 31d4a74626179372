"""Your implementations of the course's exercises.

Solution code sits between ``# BEGIN SOLUTION`` and ``# END SOLUTION``;
``python -m course release`` turns this package into ``exercises/``.
"""

#: the hint level printed into these docstrings (``python -m course release --hints N``)
HINTS_LEVEL = 0
