# RELEASE: omit
"""The reference implementation, for the judge's side only (instructor only, never in the student
tree, unreadable to the children): the oracle runs it, and a check whose hidden inputs need a
reference output (the reference Jacobians fed to an assembly) takes it from here."""

from course.core import impl as impl_loader


def reference_implementation():
    return impl_loader.load("solutions")


def solutions_module(name: str):
    """A module of the reference implementation (for inputs that need a reference output)."""
    return reference_implementation().module(name)
