"""The time a run spends in an implementation's functions: where a slow run's time goes.

``CallTimes(impl, {"elimination": ("eliminate_variable",), ...})`` is a context manager that, while it is
open, replaces each named function of the implementation's modules by a timer around it (the framework
looks a function up on its module at each call, so every call goes through the timer) and puts the
originals back on closing. ``times.rows()`` lists ``(module.function, calls, seconds)``, the slowest first.
Only the named functions are timed: a named function that calls another named one through its module counts
that time twice, so name the functions the framework calls.
"""

import time


class CallTimes:
    """Calls and seconds per named function of ``impl`` (``course.core.impl.Implementation``) while open."""

    def __init__(self, impl, functions: dict):
        self.impl = impl
        self.functions = functions
        self.calls: dict = {}
        self.seconds: dict = {}
        self._originals: list = []  # (module, name, original)

    def __enter__(self) -> "CallTimes":
        for module_name, names in self.functions.items():
            try:
                module = self.impl.module(module_name)
            except NotImplementedError:  # not handed out in this tree: nothing of it runs
                continue
            for name in names:
                original = getattr(module, name)
                self._originals.append((module, name, original))
                setattr(module, name, self._timer(f"{module_name}.{name}", original))
        return self

    def __exit__(self, *exc_info) -> None:
        for module, name, original in reversed(self._originals):
            setattr(module, name, original)
        self._originals.clear()

    def _timer(self, label: str, function):
        self.calls[label] = 0
        self.seconds[label] = 0.0

        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds[label] += time.perf_counter() - start
                self.calls[label] += 1

        return timed

    def rows(self) -> list:
        """``[(label, calls, seconds)]`` for every timed function called, the most seconds first."""
        return sorted(((label, self.calls[label], s) for label, s in self.seconds.items() if self.calls[label]),
                      key=lambda row: -row[2])

    def total(self) -> float:
        return sum(self.seconds.values())
