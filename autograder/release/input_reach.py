# RELEASE: omit
"""How much of the reference the grader's inputs reach: branch coverage of ``solutions/``.

Every check's calls, public and hidden (one seed), are run on the reference in this process
under coverage.py with branch measurement, as ``autograder.oracle.compute`` runs them. The
figure that matters is the one over the code a student writes, the lines between
``# BEGIN SOLUTION`` and ``# END SOLUTION``: a statement or a branch there that no input
reaches is one that a wrong implementation can break without losing a point. The figure over
whole files (given helpers and their argument checks included) is reported beside it.

Coverage's own formula: (statements run + branches taken) / (statements + branches), a branch
counted where its source line is. A development tool (coverage.py is a dev dependency)::

    python -m autograder.release.input_reach          # the figures, then every line or branch not reached
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from autograder.release.stubs import BEGIN, END
from course.core.impl import REPO_ROOT

SOLUTIONS = REPO_ROOT / "solutions"


@dataclass
class FileReach:
    """One file of ``solutions/``: what the inputs reach, over the graded lines and over the file."""

    path: str  # relative to the repository
    graded: tuple[int, int] = (0, 0)  # (reached, all) statements + branches between the markers
    whole: tuple[int, int] = (0, 0)  # the same over the whole file
    missed_lines: list[int] = field(default_factory=list)  # graded statements never run
    missed_branches: list[tuple[int, int]] = field(default_factory=list)  # graded (from, to) never taken
    error_lines: set[int] = field(default_factory=set)  # lines of a raise statement or an except clause

    def on_error_path(self, line: int) -> bool:
        return line in self.error_lines


@dataclass
class Reach:
    files: list[FileReach]

    @staticmethod
    def _share(pairs) -> float:
        reached, total = map(sum, zip(*pairs)) if pairs else (0, 0)
        return reached / total if total else 1.0

    @property
    def graded(self) -> float:
        """Share of the graded statements and branches that some input reaches, in [0, 1]."""
        return self._share([one.graded for one in self.files])

    @property
    def whole(self) -> float:
        return self._share([one.whole for one in self.files])

    def missed(self, errors: bool | None = None) -> list[str]:
        """``path:line`` for every graded statement not run, ``path:from->to`` for every branch not
        taken; ``errors``: True for those on an error path only (a raise, an except clause: the
        statement, or the branch's destination), False for the others, None for all."""
        out = []
        for one in self.files:
            for line in one.missed_lines:
                if errors is None or one.on_error_path(line) == errors:
                    out.append(f"{one.path}:{line}")
            for a, b in one.missed_branches:
                if errors is None or one.on_error_path(b) == errors:
                    out.append(f"{one.path}:{a}->{'exit' if b < 0 else b}")
        return out


def graded_lines(path: Path) -> set[int]:
    """The line numbers strictly between a ``# BEGIN SOLUTION`` and its ``# END SOLUTION``."""
    inside, lines = False, set()
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        text = line.strip()
        if text.startswith(BEGIN):
            inside = True
        elif text.startswith(END):
            inside = False
        elif inside:
            lines.add(number)
    return lines


def error_lines(path: Path) -> set[int]:
    """The lines of every ``raise`` statement and of every ``except`` clause (its body included)."""
    lines: set[int] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, (ast.Raise, ast.ExceptHandler)):
            lines.update(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return lines


def _run_every_check(seeds: Sequence[int | None]) -> None:
    from autograder.checks import all_checks, module_of
    from autograder.oracle import compute_fresh

    modules = module_of()
    for check in all_checks():
        for seed in seeds:
            compute_fresh(check, modules[check.name], seed)  # never the cache: every call runs here


def measure(seeds: Sequence[int | None] | None = None) -> Reach:
    """Run every check's calls on the reference under coverage; ``seeds``: ``None`` is the public
    inputs, an integer the hidden ones of that seed (default: public and the default hidden seed).

    Run it in a fresh process: the oracle remembers the outputs it computed, and a call it does not
    run again is not measured.
    """
    import coverage

    from autograder.oracle import hidden_seed

    seeds = [None, hidden_seed()] if seeds is None else list(seeds)
    measured = coverage.Coverage(branch=True, source=[str(SOLUTIONS)], data_file=None)
    measured.start()
    try:
        _run_every_check(seeds)
    finally:
        measured.stop()
    with tempfile.TemporaryDirectory() as scratch:
        report = Path(scratch) / "coverage.json"
        measured.json_report(outfile=str(report))
        data = json.loads(report.read_text(encoding="utf-8"))
    files = []
    for name, one in sorted(data["files"].items()):
        path = Path(name) if Path(name).is_absolute() else REPO_ROOT / name
        graded = graded_lines(path)
        run, missing = one["executed_lines"], one["missing_lines"]
        taken, not_taken = one["executed_branches"], one["missing_branches"]
        files.append(FileReach(
            path=path.relative_to(REPO_ROOT).as_posix(),
            graded=(sum(line in graded for line in run) + sum(a in graded for a, _ in taken),
                    sum(line in graded for line in run + missing) + sum(a in graded for a, _ in taken + not_taken)),
            whole=(len(run) + len(taken), len(run) + len(missing) + len(taken) + len(not_taken)),
            missed_lines=[line for line in missing if line in graded],
            missed_branches=[(a, b) for a, b in not_taken if a in graded],
            error_lines=error_lines(path),
        ))
    return Reach(files)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m autograder.release.input_reach",
                                     description=__doc__.split("\n")[0])
    parser.add_argument("--json", action="store_true", help="print the figures and the misses as JSON")
    options = parser.parse_args(argv)
    reach = measure()
    if options.json:
        print(json.dumps({"graded": reach.graded, "whole": reach.whole, "missed": reach.missed(),
                          "missed_errors": reach.missed(errors=True), "missed_others": reach.missed(errors=False)}))
        return 0
    print(f"graded lines of solutions/ (between the markers): {100 * reach.graded:.1f}% of statements and branches "
          "reached by the checks' public and hidden inputs")
    print(f"whole files (given helpers and their argument checks too): {100 * reach.whole:.1f}%")
    for line in reach.missed(errors=False):
        print(f"  not reached: {line}")
    for line in reach.missed(errors=True):
        print(f"  not reached, an error path: {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
