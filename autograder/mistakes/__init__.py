# RELEASE: omit
"""The catalogue of known student mistakes, one module per check module (instructor only).

``autograder/mistakes/<module>.py`` holds ``MISTAKES = {check name: known}`` where
``known(call, reference_fields)`` returns ``{key: [(value, why), ...]}``: the output a
known wrong formula gives on the call's inputs, and the likely cause feedback names when
the student's output matches it. The formulas sit one slip away from the reference, so
they never ship to students: :mod:`autograder.oracle` evaluates them on the public
inputs at release time (the values ship as data) and on the hidden inputs when grading.
"""
