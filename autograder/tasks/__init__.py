"""Framework runs that a check asks the child to perform with the student's code.

A task is a function taking ``impl=`` (the loaded implementation) and returning a
dict of numbers or arrays. The parent calls the same function with ``solutions``
for the reference; the child calls it with the student's implementation (a call
target ``"@autograder.tasks.end_to_end:minimize_curve"``).

One module per exercise, named after its check module (``tasks/dogleg.py`` serves
``checks/dogleg.py``), and :mod:`autograder.tasks.common` for what several share.
The tasks return only numbers and arrays (the child writes nothing else): a string
such as the dogleg case comes back as its character codes. A task that instruments
the implementation (a stand-in for a function, a counter around a library class)
does so only when it is the only Python thread, i.e. in the child: the parent
computes the reference outputs in worker threads that share modules.

The child imports these modules from a staged copy (:func:`autograder.isolation.stage_framework`):
they import ``course`` and each other only. This ``__init__`` imports nothing.
"""
