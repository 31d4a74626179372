"""Reference implementations of the course's exercises.

Solution code sits between ``# BEGIN SOLUTION`` and ``# END SOLUTION``;
``python -m course release`` turns this package into ``exercises/``.
"""
