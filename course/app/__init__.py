"""The application: the command line, compare, the benchmarks, plots, the VIO comparison.

Importing it keeps freed memory in the process (:mod:`course.core.allocator`): every solve and
benchmark run from here avoids page-faulting its temporaries again at each iteration.
"""

from course.core.allocator import keep_freed_memory

keep_freed_memory()
