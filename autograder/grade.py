"""Run the checks: one child process per check, two at a time, judged in the parent.

The parent loads only ``solutions`` (for the reference outputs) and the framework;
the implementation being graded is named by a string and loaded in the children.
"""

import sys
import time
import traceback
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from autograder import sandbox
from autograder.checks import Context, Outcome, Verdict, all_checks, select
from autograder.child import run_calls

PRINTED_LINES = 5


@dataclass
class CheckResult:
    name: str
    exercise: str
    score: float
    max_score: float
    message: str  # the whole feedback
    not_implemented: tuple = ()
    printed: str = ""
    seconds: float = 0.0

    @property
    def title(self) -> str:
        prefix = self.exercise + ": "
        return self.name[len(prefix):] if self.name.startswith(prefix) else self.name

    @property
    def full(self) -> bool:
        return self.score >= self.max_score - 1e-9


def reference_outcomes(calls) -> list:
    """The reference implementation's outputs, computed here (trusted code)."""
    from course import impl as impl_loader

    solutions = impl_loader.load("solutions")
    with np.errstate(all="ignore"):
        results = run_calls(solutions, [c.payload() for c in calls])
    outcomes = []
    for call, result in zip(calls, results):
        if not isinstance(result, tuple):
            raise RuntimeError(f"the reference failed on {call.function} {call.where}: {result}")
        kind, fields = result
        outcomes.append(Outcome(fields=fields, kind=kind))
    return outcomes


def grade_check(check, impl: str, timeout: float, memory_mb: float) -> CheckResult:
    calls = check.calls()
    reference = reference_outcomes(calls)
    limit = check.timeout or timeout
    child = sandbox.run(impl, calls, timeout=limit, memory_mb=memory_mb)
    context = Context(check, calls, child.outcomes, reference, child.printed)
    try:
        with np.errstate(all="ignore"):
            verdict = check.judge(context)
    except Exception as exc:  # noqa: BLE001 - odd output the judge did not foresee
        print(f"autograder: the judge of {check.name!r} failed:\n{traceback.format_exc()}", file=sys.stderr)
        verdict = Verdict(0.0, f"the grader could not judge this output ({type(exc).__name__}: {exc})")
    fraction = min(max(float(verdict.fraction), 0.0), 1.0)
    message = verdict.message
    if fraction < 1.0 and child.printed.strip() and not verdict.not_implemented:
        lines = child.printed.strip("\n").splitlines()
        shown = "\n".join(f"  | {line[:160]}" for line in lines[:PRINTED_LINES])
        more = f"\n  | ... ({len(lines) - PRINTED_LINES} more lines)" if len(lines) > PRINTED_LINES else ""
        message += f"\nYour code printed (shown for information, never graded):\n{shown}{more}"
    return CheckResult(check.name, check.exercise, round(check.points * fraction, 4), float(check.points),
                       message, tuple(verdict.not_implemented), child.printed, child.seconds)


def grade(impl: str, only=None, timeout=sandbox.DEFAULT_TIMEOUT, memory_mb=sandbox.DEFAULT_MEMORY_MB,
          workers=2, checks=None) -> list:
    """Grade ``impl`` ("solutions", "exercises" or a path) on the selected checks, in order."""
    checks = select(checks if checks is not None else all_checks(), only)
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        futures = [pool.submit(grade_check, check, str(impl), timeout, memory_mb) for check in checks]
        return [future.result() for future in futures]


def run(impl, only=None, **kwargs):
    """``(results, seconds)``."""
    start = time.perf_counter()
    results = grade(impl, only, **kwargs)
    return results, time.perf_counter() - start
