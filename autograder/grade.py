"""Run the checks: one child process per check, ``workers`` at a time, judged here.

Every check comes in two sets. The **public** set runs on the inputs shipped in
``autograder/expected/`` and is judged against the reference outputs recorded there (a
student grades it locally, without the reference). The **hidden** set is the same checks
on fresh inputs from the hidden seed, judged against the reference computed here from
``solutions`` (:mod:`autograder.oracle`, instructor side only), and reported to Gradescope
with ``visibility: after_published``.

Every expected output exists before the first child starts; results are written by the
caller after :func:`grade` returns, when every child is gone. A check that needs a library
not installed here (``Check.needs``, e.g. pyceres) is not run: it scores 0 and says why,
and the library's absence is said once (``course.core.peers``).

Before anything of an implementation runs, its files' imports are read against the exercises'
contracts (:func:`screen`, :mod:`autograder.allowed_imports`): the checks of a refused file score 0
with the refusal's line, and the file is graded as an unwritten TODO wherever another exercise uses it.
"""

import shutil
import sys
import tempfile
import threading
import time
import traceback
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from autograder import expected as expected_data
from autograder import point_grid, sandbox
from autograder.checks import all_checks, module_of, select
from autograder.records import Check, Context, Verdict
from course.core import peers

PRINTED_LINES = 5
SETS = ("public", "hidden", "all")
HIDDEN_SUFFIX = " (hidden inputs)"


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
    hidden: bool = False
    status: str = "ok"  # ok | timeout | crashed (the child) | not run
    mistake: str = ""  # the known mistake the output matched (its likely cause), if any
    #: in an assignment (autograder.course_config): Gradescope's visibility ("" = the default: visible, hidden
    #: checks after_published), extra credit (its points not in the maximum), counted (a hidden check whose
    #: assignment does not count them is shown and scores nothing)
    visibility: str = ""
    extra: bool = False
    counted: bool = True

    @property
    def title(self) -> str:
        prefix = self.exercise + ": "
        return self.name[len(prefix):] if self.name.startswith(prefix) else self.name

    @property
    def full(self) -> bool:
        return self.score >= self.max_score - 1e-9


@dataclass
class Task:
    """One check on one set of inputs, with what its judge compares against."""

    check: Check
    hidden: bool
    expected: expected_data.Expected | None  # None when not run (``missing``, ``ungradable``)
    missing: str = ""  # a library the check needs that is not installed here
    ungradable: str = ""  # why the reference could not give this check's expected outputs

    @property
    def name(self) -> str:
        return self.check.name + (HIDDEN_SUFFIX if self.hidden else "")


def reference_available() -> bool:
    """True in the instructor's tree (the reference and the oracle are importable)."""
    import importlib.util

    return all(importlib.util.find_spec(name) is not None for name in ("solutions", "autograder.oracle"))


def default_set() -> str:
    return "all" if reference_available() else "public"


def missing_library(check: Check) -> str:
    """The first library of ``check.needs`` not installed here ("" when all are)."""
    return next((name for name in check.needs if not peers.installed(name)), "")


def plan(checks, which: str) -> list:
    """The tasks of ``which`` ("public", "hidden" or "all"), each with its expected outputs
    (none for a check whose library is missing here: it is not run)."""
    if which not in SETS:
        raise ValueError(f"unknown set {which!r}; one of {', '.join(SETS)}")
    modules = module_of()
    tasks = []
    if which in ("public", "all"):
        shipped = {}
        for check in checks:
            module = modules[check.name]
            if module not in shipped:
                shipped[module] = expected_data.load(module)
            if check.name not in shipped[module]:
                raise expected_data.ExpectedDataError(
                    f"autograder/expected/{module}.json has no data for {check.name!r}: "
                    "run `python -m course release` (instructor)")
            tasks.append(Task(check, False, shipped[module][check.name], missing_library(check)))
    if which in ("hidden", "all"):
        from autograder import oracle

        seed = oracle.hidden_seed()
        for check in checks:
            missing = missing_library(check)
            try:
                expected = None if missing else oracle.compute(check, modules[check.name], seed)
            except oracle.ReferenceFailed as exc:
                print(f"autograder: NOT GRADABLE: {check.name}{HIDDEN_SUFFIX}: {exc}. This check counts for "
                      "no one (0 of 0 points) and every other check is graded; instructor: fix the reference or "
                      "the check's inputs", file=sys.stderr)
                tasks.append(Task(check, True, None, ungradable=str(exc)))
                continue
            tasks.append(Task(check, True, expected, missing))
    return tasks


def not_gradable(task: Task) -> CheckResult:
    """A check whose reference failed on its inputs: it counts for no one (0 of 0 points)."""
    message = (f"not gradable: the reference solution failed on this check's inputs ({task.ungradable}); it counts "
               "for no one (0 of 0 points) and the instructor has been told")
    return CheckResult(task.name, task.check.exercise, 0.0, 0.0, message, hidden=task.hidden, status="not gradable")


def not_run(task: Task) -> CheckResult:
    """The result of a check whose library is not installed here: 0 points, and why."""
    message = (f"not run: {task.missing} is not installed here, and this check needs it; it runs where "
               f"{task.missing} is (Gradescope has it): `{peers.INSTALL[task.missing]}` where it has a wheel")
    return CheckResult(task.name, task.check.exercise, 0.0, point_grid.on_grid(task.check.points), message,
                       hidden=task.hidden, status="not run")


def known_mistake(message: str, expected: expected_data.Expected) -> str:
    """The likely cause of the known mistake ``message`` names ('' when none): feedback ends a
    comparison that matched a known mistake with ``": " + why``."""
    for per_call in expected.mistakes:
        for pairs in per_call.values():
            for _, why in pairs:
                if why and f": {why}" in message:
                    return why
    return ""


def judge_task(task: Task, child) -> CheckResult:
    check, want = task.check, task.expected
    assert want is not None  # a task that runs has its expected outputs
    context = Context(check, want.calls, child.outcomes, want.reference, child.printed, want.mistakes)
    try:
        with np.errstate(all="ignore"):
            verdict = check.judge(context)
    except Exception as exc:  # noqa: BLE001 - odd output the judge did not foresee
        print(f"autograder: the judge of {task.name!r} failed:\n{traceback.format_exc()}", file=sys.stderr)
        verdict = Verdict(0.0, f"the grader could not judge this output ({type(exc).__name__}: {exc})")
    fraction = min(max(float(verdict.fraction), 0.0), 1.0)
    message = verdict.message
    if fraction < 1.0 and child.printed.strip() and not verdict.not_implemented:
        lines = child.printed.strip("\n").splitlines()
        shown = "\n".join(f"  | {line[:160]}" for line in lines[:PRINTED_LINES])
        more = f"\n  | ... ({len(lines) - PRINTED_LINES} more lines)" if len(lines) > PRINTED_LINES else ""
        message += f"\nYour code printed (shown for information, never graded):\n{shown}{more}"
    mistake = known_mistake(verdict.message, want) if fraction < 1.0 else ""
    # on one grid (autograder.point_grid): a full fraction scores the maximum itself
    return CheckResult(task.name, check.exercise, point_grid.scaled(check.points, fraction),
                       point_grid.on_grid(check.points), message, tuple(verdict.not_implemented), child.printed,
                       child.seconds, task.hidden, child.status, mistake)


class Hung:
    """The functions of one implementation that ran out of time, so that a function that
    hangs costs one timeout, not one per check that calls it: ``blocked(calls)`` says why a
    check whose calls include one of them is not run."""

    def __init__(self):
        self._lock = threading.Lock()
        self._where: dict = {}  # call (its function, or IMPORT) -> (function, the check where it timed out)

    IMPORT = "<import>"

    def record(self, task: "Task", child) -> None:
        if child.status != "timeout" or child.by_budget:
            return
        calls = task.expected.calls if task.expected is not None else []
        if 0 <= child.running < len(calls):  # a framework task is told apart by its label (its method)
            key = function = calls[child.running].function
        else:  # it hung before the first call: loading the implementation
            key, function = self.IMPORT, "loading your code"
        with self._lock:
            self._where.setdefault(key, (function, task.name))

    def blocked(self, calls) -> str:
        with self._lock:
            for key in [self.IMPORT] + [call.function for call in calls]:
                if key in self._where:
                    function, check = self._where[key]
                    return f"not run: {function} timed out in {check!r}, so this check would too"
        return ""


def skipped(task: "Task", why: str) -> CheckResult:
    """A check not run because a function it calls already timed out: 0 points, and why."""
    return CheckResult(task.name, task.check.exercise, 0.0, point_grid.on_grid(task.check.points), why,
                       hidden=task.hidden, status="not run")


def grade(impl: str, only=None, timeout=sandbox.DEFAULT_TIMEOUT, memory_mb=sandbox.DEFAULT_MEMORY_MB,
          workers=2, checks=None, which=None, budget=None, notices=None, assignment=None) -> list:
    """Grade ``impl`` ("solutions", "exercises" or a path) on the selected checks, in order.

    ``which``: "public", "hidden" or "all" (default: all where the reference is, else
    public). ``notices``: a list that receives the sandbox's one-line notice, if any.
    ``assignment``: an :class:`autograder.course_config.Assignment` (see :func:`grade_many`).
    """
    return grade_many([impl], only, timeout, memory_mb, workers, checks, which, budget, notices,
                      assignment=assignment)[0]


def given_folder() -> Path:
    """Where the solved exercise files come from: ``autograder/given/`` in a released tree or zip
    (the reference of the assignment's ``solved`` files, as released), else ``solutions/``."""
    from course.core.impl import REPO_ROOT

    given = Path(__file__).resolve().parent / "given"
    return given if given.is_dir() else REPO_ROOT / "solutions"


def compose(impl: str, solved, target: Path, given: Path | None = None) -> str:
    """A package at ``target``: the exercise files of ``impl`` (a name or a path), with each module of
    ``solved`` replaced by the given (solved) code of :func:`given_folder`. An assignment grades this,
    so that the pieces it does not grade (the curve model of dogleg's end-to-end runs) are the solved
    code whatever the submission holds: its grade depends on its own files alone."""
    from course.core.impl import BUILTIN, REPO_ROOT

    source = REPO_ROOT / impl if impl in BUILTIN else Path(impl)
    given = given_folder() if given is None else given
    target.mkdir(parents=True)
    for path in sorted(source.glob("*.py")):
        if path.is_file() and not path.is_symlink():
            shutil.copyfile(path, target / path.name)
    for module in solved:
        origin = given / f"{module}.py"
        if not origin.is_file():
            raise FileNotFoundError(f"{origin}: the solved code of {module} is missing")
        shutil.copyfile(origin, target / f"{module}.py")
    return str(target)


def mark(result: CheckResult, check: Check, assignment) -> CheckResult:
    """``result`` with its assignment's visibility, extra credit and counting."""
    if assignment is None:
        return result
    result.visibility = assignment.hidden_visibility if result.hidden else "visible"
    result.extra = assignment.is_extra(check)
    result.counted = not result.hidden or assignment.hidden_counts
    return result


def grade_many(impls, only=None, timeout=sandbox.DEFAULT_TIMEOUT, memory_mb=sandbox.DEFAULT_MEMORY_MB,
               workers=2, checks=None, which=None, budget=None, notices=None, on_done=None, on_check=None,
               catalogue=True, assignment=None, each=None) -> list:
    """Grade each implementation of ``impls`` as :func:`grade` does, in one run: the expected
    outputs computed once, one sandbox session, ``workers`` children at a time across all of
    them. Returns one list of results per implementation, in order. ``budget`` is per
    implementation.

    ``on_done(index, results)`` is called (from a worker thread, one call at a time) as soon
    as every check of ``impls[index]`` is judged; ``on_check(index, result)`` after each check.
    Once a function of an implementation has timed out, its other checks that call it are
    not run (:class:`Hung`). ``catalogue=False`` judges as if no mistake were known (the
    instructor's measure of the feedback on mistakes nobody foresaw).

    ``assignment`` (:class:`autograder.course_config.Assignment`): grade its checks (default for
    ``checks``) with its points, each result marked with its visibility, extra credit and counting,
    and each implementation composed with the assignment's solved files (:func:`compose`). Without
    it, every piece a check runs is the implementation's own, as before.

    ``each``: per implementation, the names of the checks (of those selected) to grade it on; its
    list of results holds those alone. None: every implementation on every selected check.
    """
    impls = [str(impl) for impl in impls]
    if checks is None:
        checks = assignment.checks() if assignment is not None else all_checks()
    checks = select(checks, only)
    with tempfile.TemporaryDirectory(prefix="autograder-compose-") as scratch:
        shown = [_display(impl) for impl in impls]
        if assignment is not None and assignment.solved:
            impls = [compose(impl, assignment.solved, Path(scratch) / str(index))
                     for index, impl in enumerate(impls)]
        impls, refused = screen(impls, shown, Path(scratch) / "screened")
        return _grade_many(impls, checks, timeout, memory_mb, workers, which, budget, notices, on_done, on_check,
                           catalogue, assignment, refused, each)


def _display(impl: str) -> str:
    """How a refusal names the folder of ``impl``: ``exercises`` or the folder's name."""
    from course.core.impl import BUILTIN

    return impl if impl in BUILTIN else Path(impl).name


def screen(impls, shown, scratch: Path) -> tuple:
    """Check each implementation's imports against the exercises' contracts
    (:mod:`autograder.allowed_imports`) before anything of it runs. Returns the implementations to
    grade (a copy with each refused file made an unwritten TODO, where one is) and, per
    implementation, ``{module: the refusal's line}``."""
    from autograder import allowed_imports
    from course.core.impl import BUILTIN, REPO_ROOT

    try:
        contracts = allowed_imports.load_contracts()
    except allowed_imports.ContractError as exc:  # shipped data, as the expected outputs: the same report
        raise expected_data.ExpectedDataError(str(exc)) from None
    out, refused = [], []
    for index, (impl, name) in enumerate(zip(impls, shown)):
        folder = REPO_ROOT / impl if impl in BUILTIN else Path(impl)
        found = allowed_imports.refusals(folder, name, contracts)
        if found:
            copy = scratch / str(index)
            copy.mkdir(parents=True)
            for path in sorted(folder.glob("*.py")):  # as compose: the package's own files, no symlink
                if path.is_file() and not path.is_symlink():
                    shutil.copyfile(path, copy / path.name)
            allowed_imports.neutralise(copy, found)
            impl = str(copy)
        out.append(impl)
        refused.append(found)
    return out, refused


def with_refusals(result: CheckResult, refused: dict) -> CheckResult:
    """``result`` saying why a TODO it names is unwritten, where its file was refused for its imports."""
    modules = dict.fromkeys(name.split(".")[0] for name in result.not_implemented)
    lines = [refused[module] for module in modules if module in refused]
    if lines:
        result.message += "".join(f"\n{line}" for line in lines)
    return result


def refusal(task: Task, why: str) -> CheckResult:
    """A check of an exercise file the grader refused for its imports: 0 points, and the refusal."""
    return CheckResult(task.name, task.check.exercise, 0.0, float(task.check.points), why, hidden=task.hidden,
                       status="refused")


def _grade_many(impls, checks, timeout, memory_mb, workers, which, budget, notices, on_done, on_check, catalogue,
                assignment, refused, each=None) -> list:
    tasks = plan(checks, which or default_set())
    owner = module_of()
    if notices is not None:  # a refused __init__.py has no check of its own: said once
        notices += [found["__init__"] for found in refused if "__init__" in found]
    if not catalogue:
        tasks = [replace(task, expected=task.expected.without_catalogue()) if task.expected else task
                 for task in tasks]
    for library in sorted({task.missing for task in tasks if task.missing}):
        peers.announce(library)
    total = None if budget is None else budget * len(impls)
    hung = [Hung() for _ in impls]
    jobs = [(index, number, task) for index in range(len(impls)) for number, task in enumerate(tasks)
            if each is None or task.check.name in each[index]]
    per_impl = Counter(index for index, _, _ in jobs)
    left = [per_impl[index] for index in range(len(impls))]
    results: list = [[None] * len(tasks) for _ in impls]
    report = threading.Lock()
    with sandbox.Session(impls[0], timeout=timeout, memory_mb=memory_mb, workers=workers,
                         budget=total) as session:
        if notices is not None and session.notice:
            notices.append(session.notice)
        staged = [session.prepare(impl) for impl in impls]

        def one(job):
            index, number, task = job
            # the checks of a refused file are not run; a run of several files (end_to_end) runs, with the
            # refused one an unwritten TODO that says why
            why = refused[index].get(owner.get(task.check.name, ""), "")
            if why:
                result = refusal(task, why)
            elif task.ungradable:
                result = not_gradable(task)
            elif task.missing:
                result = not_run(task)
            else:
                assert task.expected is not None
                blocked = hung[index].blocked(task.expected.calls)
                if blocked:
                    result = skipped(task, blocked)
                else:
                    child = session.run(task.expected.calls, timeout=task.check.timeout or timeout,
                                        impl=staged[index])
                    hung[index].record(task, child)
                    result = with_refusals(judge_task(task, child), refused[index])
            result = mark(result, task.check, assignment)
            with report:
                results[index][number] = result
                left[index] -= 1
                if on_check is not None:
                    on_check(index, result)
                if left[index] == 0 and on_done is not None:
                    on_done(index, results[index] if each is None else [r for r in results[index] if r is not None])

        with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
            list(pool.map(one, jobs))
    if each is not None:
        return [[result for result in row if result is not None] for row in results]
    return results


def run(impl, only=None, **kwargs):
    """``(results, seconds)``."""
    start = time.perf_counter()
    results = grade(impl, only, **kwargs)
    return results, time.perf_counter() - start
