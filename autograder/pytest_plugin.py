"""pytest as a front door to the autograder: ``pytest exercises`` grades that folder, one test per check.

Enabled with ``-p autograder.pytest_plugin``, which the student tree's ``pytest.ini`` and the
instructor's ``pyproject.toml`` put in ``addopts``.

**Collection.** A folder pytest reaches is graded when it is laid out like ``exercises/``: an
``__init__.py`` and files named after more than half of the check modules (``exercises/``,
``solutions/``, a copy or a submission, wherever it is; a missing file fails its checks).
:func:`pytest_collect_directory` claims it before pytest's ``Package`` would, so nothing of it is
imported in pytest's process (only a ``conftest.py`` put in it would be: pytest loads every
conftest). The folder yields one collector per exercise file (its path is the file, so editors
link to it) and one per check module that grades several files together (``end_to_end``,
``pose_graph``); each holds one item per check, named with its points
(``exercises/damping.py::GavinType1: update (accepted step) [1 pt]``), and a hidden-input item
per check too where the set graded is "all" (the instructor's tree,
``autograder.grade.default_set``; ``--autograder-set`` picks another). Any other folder is left
to pytest, so a test suite beside it (``tests/``) collects as before.

**Selecting.** ``-k`` matches any part of an item's name (``-k pose_graph`` also takes
``pose_graph_3d.py``); each item carries its check module's name as a marker, and ``-m`` matches
marker names exactly: ``-m pose_graph`` selects that exercise's checks and no other
(``-m "pose_graph_edge or pose_graph_assembly"`` several).

**Running.** The first item of a folder that runs grades every selected item of that folder
(after ``-k``, ``--lf``, ``--deselect``) in one grading run, ``autograder.grade.grade`` with two
workers: the same children, judge and feedback as ``python -m autograder``. Each item then reports
its own result: full marks pass; fewer fail, and the failure is the autograder's feedback, without
a traceback; a check not run because a library is missing here is skipped, saying so. The judge
runs its own two workers: ``pytest -n`` (xdist) would grade once per worker.

**Points.** The terminal summary ends with the points of the items that ran (skipped ones score 0,
as in the autograder's table): ``autograder: 14 / 30 points on the 12 checks run (public
checks)``; with every check run, the total of ``python -m autograder --impl SAME --set SAME``.
"""

import contextlib
import functools
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import pytest

CHECKS_DIR = Path(__file__).resolve().parent / "checks"
NOT_CHECKS = ("__init__", "common")
SET_WORDS = {"public": "public checks", "hidden": "hidden checks", "all": "public and hidden checks"}


def pytest_addoption(parser):
    group = parser.getgroup("autograder", "grading an implementation folder (autograder.pytest_plugin)")
    group.addoption("--autograder-set", choices=("public", "hidden", "all"), default=None,
                    help="the checks to collect: public (shipped inputs), hidden (fresh inputs, judged with the "
                         "reference: instructor only) or all; default: all where the reference is, else public")
    group.addoption("--autograder-only", action="append", metavar="NAME", default=None,
                    help="keep only the checks of this check module, exercise or check, by its exact name (as "
                         "python -m autograder --only); repeatable")


def check_module_names() -> list:
    """The check modules' names (``autograder/checks/NAME.py``), read from the folder (nothing imported)."""
    return sorted(entry.stem for entry in CHECKS_DIR.glob("*.py") if entry.stem not in NOT_CHECKS)


def pytest_configure(config):
    config.addinivalue_line("markers", "public: an autograder check on the inputs shipped with the course")
    config.addinivalue_line("markers", "hidden: an autograder check on fresh inputs, judged with the reference")
    for name in check_module_names():  # -m NAME: one exercise exactly (-k matches any part of a name)
        config.addinivalue_line("markers", f"{name}: the autograder checks of {name} (select them with -m {name})")
    if config.getoption("autograder_set"):
        which_set(config)  # a usage error now rather than at collection


def which_set(config) -> str:
    from autograder.grade import default_set, reference_available

    which = config.getoption("autograder_set") or default_set()
    if which != "public" and not reference_available():
        raise pytest.UsageError(f"--autograder-set {which}: the hidden checks are judged with the reference, "
                                "which this tree does not have; use public")
    return which


@functools.cache
def assignment():
    """The assignment a released tree grades (``autograder/ASSIGNMENT``: its check modules only, with
    its points), or None: every check."""
    from autograder import course_config

    name = course_config.current_assignment()
    return course_config.load().assignment(name) if name else None


def is_implementation(path: Path) -> bool:
    """True for a folder laid out like ``exercises/`` (see the module docstring). It reads names
    only: the check modules (``autograder/checks/NAME.py``), named after the exercise files they
    grade, and the folder's files; the framework's packages hold one such name at most."""
    try:
        if not (path / "__init__.py").is_file():
            return False
        files = {entry.stem for entry in path.iterdir() if entry.suffix == ".py"}
    except OSError:
        return False
    graded = assignment()
    if graded is not None:  # an assignment's tree: its own exercise files
        names = set(graded.modules)
    else:
        names = {entry.stem for entry in CHECKS_DIR.glob("*.py")} - set(NOT_CHECKS)
    return 2 * len(files & names) > len(names)


def pytest_collection_modifyitems(session, config, items):
    """``--autograder-only NAME``: deselect the checks ``NAME`` does not name (exact names, as
    :func:`autograder.checks.select`); a name that names none is a usage error listing the close ones."""
    names = config.getoption("autograder_only")
    if not names:
        return
    from autograder.checks import SelectionError, select

    checks: list = []
    for item in items:
        if isinstance(item, CheckItem) and item.check not in checks:
            checks.append(item.check)
    try:
        chosen = {check.name for check in select(checks, names)}
    except SelectionError as exc:
        raise pytest.UsageError(f"--autograder-only: {exc}") from None
    kept = [item for item in items if not isinstance(item, CheckItem) or item.check.name in chosen]
    dropped = [item for item in items if isinstance(item, CheckItem) and item.check.name not in chosen]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = kept


@pytest.hookimpl(tryfirst=True)
def pytest_collect_directory(path, parent):
    if is_implementation(path):
        return ImplementationFolder.from_parent(parent, path=path)
    return None


def points_text(points: float) -> str:
    return f"[{points:g} pt]" if points == 1 else f"[{points:g} pts]"


class ImplementationFolder(pytest.Directory):
    """An implementation of the exercises: its exercise files and the checks that grade several."""

    def collect(self):
        from autograder.checks import modules

        which = which_set(self.config)
        hidden_sets = {"public": (False,), "hidden": (True,), "all": (False, True)}[which]
        graded = assignment()
        points = {check.name: check for check in graded.checks()} if graded is not None else {}
        for name, module in modules():
            if graded is not None and name not in graded.exercises:
                continue
            if name in module.MODULES:
                group = ExerciseFile.from_parent(self, path=self.path / f"{name}.py")
            else:
                group = CheckGroup.from_parent(self, name=name)
            group.entries = [(points.get(check.name, check), hidden) for check in module.CHECKS
                             for hidden in hidden_sets]
            # extra credit is the assignment's word (its ``optional``), not the check's name
            group.extra = frozenset(c.name for c in module.CHECKS if graded is not None and graded.is_extra(c))
            group.prefix, group.folder = name, self.path.resolve()
            yield group


class ChecksOf:
    """What an exercise file and a check group share: one item per (check, set)."""

    entries: list
    prefix: str
    folder: Path
    extra: frozenset = frozenset()  # the checks of an optional exercise (extra credit)

    def collect(self):
        for check, hidden in self.entries:
            title = check.name
            for head in (self.prefix + ".", self.prefix + ": "):
                if title.startswith(head):
                    title = title[len(head):]
                    break
            if hidden:
                from autograder.grade import HIDDEN_SUFFIX

                title += HIDDEN_SUFFIX
            if check.name in self.extra:
                title += " (extra credit)"
            name = f"{title} {points_text(check.points)}"
            # the id from its text, as pytest reads ids back (``--lf``'s cache): a "[" there opens
            # parameters, and the names hold brackets ("[2 pts]", "lambda clamped to [1e-7, 1e7]")
            yield CheckItem.from_parent(self, name=name, nodeid=f"{self.nodeid}::{name}", check=check,
                                        hidden=hidden, folder=self.folder, module=self.prefix)


class ExerciseFile(ChecksOf, pytest.File):
    """The checks of one exercise file (``exercises/damping.py``); the file is never imported."""


class CheckGroup(ChecksOf, pytest.Collector):
    """The checks of a check module that grades several files together (``end_to_end``)."""


class CheckFailed(Exception):
    """A check below full marks; its text is the autograder's feedback."""


@dataclass
class FolderGrading:
    """One folder's grading run: its results by name, and those of the items reported so far."""

    results: dict = field(default_factory=dict)
    error: str = ""
    output: str = ""  # what the grading run printed (notices, a missing library said once)
    notices: list = field(default_factory=list)
    reported: list = field(default_factory=list)
    not_run: set = field(default_factory=set)  # names of the results skipped for a missing library


GRADINGS = pytest.StashKey[dict]()


def gradings(config) -> dict:
    """``{folder: FolderGrading}`` of this pytest session."""
    return config.stash.setdefault(GRADINGS, {})


def impl_argument(folder: Path) -> str:
    """``exercises`` or ``solutions`` for the repository's own folders (as ``make check`` names
    them), else the folder's path."""
    from course.core.impl import BUILTIN, REPO_ROOT

    for name in BUILTIN:
        if folder == (REPO_ROOT / name).resolve():
            return name
    return str(folder)


class CheckItem(pytest.Item):
    """One check of one set (public or hidden inputs) on the folder's implementation."""

    def __init__(self, *, check, hidden: bool, folder: Path, module: str = "", **kwargs):
        super().__init__(**kwargs)
        self.check, self.hidden, self.folder = check, hidden, folder
        self.add_marker("hidden" if hidden else "public")
        if module:  # its check module's name as a marker: ``-m pose_graph`` selects those checks exactly
            self.add_marker(module)

    @property
    def result_name(self) -> str:
        from autograder.grade import HIDDEN_SUFFIX

        return self.check.name + (HIDDEN_SUFFIX if self.hidden else "")

    def grading(self) -> FolderGrading:
        """This folder's grading run; the first item to ask starts it, for every selected item."""
        runs = gradings(self.config)
        if self.folder not in runs:
            runs[self.folder] = grade_items([item for item in self.session.items
                                             if isinstance(item, CheckItem) and item.folder == self.folder])
        return runs[self.folder]

    def runtest(self):
        from autograder.grade import missing_library

        run = self.grading()
        if run.error:
            raise CheckFailed(run.error)
        result = run.results[self.result_name]
        run.reported.append(result)
        if missing_library(self.check):
            run.not_run.add(result.name)
            pytest.skip(result.message)
        if not result.full:
            raise CheckFailed(result.message)

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, CheckFailed):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style)

    def reportinfo(self):
        return self.path, line_of(self.path, self.check.exercise), self.name


def line_of(path: Path, exercise: str):
    """The 0-based line of the class or function an exercise names (``damping.GavinType1``), read
    as text (never imported); None when not found."""
    head = exercise.split(".")[1] if "." in exercise else ""
    if not head or not path.is_file():
        return None
    pattern = re.compile(rf"^(class|def)\s+{re.escape(head)}\b")
    for number, line in enumerate(path.read_text(errors="replace").splitlines()):
        if pattern.match(line):
            return number
    return None


def grade_items(items: list) -> FolderGrading:
    """Grade the checks of ``items`` (all of one folder) in one run of the autograder."""
    from autograder.expected import ExpectedDataError
    from autograder.grade import grade
    from autograder.isolation import IsolationError

    run = FolderGrading()
    checks = []
    for item in items:
        if item.check not in checks:
            checks.append(item.check)
    sets = {item.hidden for item in items}
    which = "all" if len(sets) == 2 else ("hidden" if True in sets else "public")
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            results = grade(impl_argument(items[0].folder), checks=checks, which=which, workers=2,
                            notices=run.notices, assignment=assignment())
    except (ExpectedDataError, IsolationError) as exc:
        run.error = f"autograder: {exc}"
        results = []
    run.output = printed.getvalue()
    run.results = {result.name: result for result in results}
    return run


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_terminal_summary(terminalreporter, config):
    """After pytest's own summary (the short one included), before the final counts: the points."""
    from autograder.report import next_step, total

    yield
    runs = gradings(config)
    for folder, run in runs.items():
        for line in [*run.notices, *run.output.strip().splitlines()]:
            terminalreporter.write_line(line if line.startswith("autograder") else f"autograder: {line}")
        if not run.reported:
            continue
        sets = {result.hidden for result in run.reported}
        which = "all" if len(sets) == 2 else ("hidden" if True in sets else "public")
        where = f" in {folder}" if len(runs) > 1 else ""
        count = len(run.reported)
        not_run = sum(1 for result in run.reported if result.name in run.not_run)
        note = f"; {not_run} not run here score 0: a library is missing" if not_run else ""
        terminalreporter.write_line(f"autograder: {total(run.reported)} points on the {count} "
                                    f"check{'s' if count != 1 else ''} run{where} ({SET_WORDS[which]}{note})",
                                    bold=True)
        step = next_step(run.reported)
        if step:
            terminalreporter.write_line(f"autograder: {step}")
