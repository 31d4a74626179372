"""``python -m autograder [--impl exercises|solutions|PATH] [--assignment NAME] [--only NAME] [--set public|hidden|all]
[--json FILE] [--metadata submission_metadata.json]``,
or a whole class: ``python -m autograder batch SUBMISSIONS --out DIR``, ``python -m autograder
merge PART... --out DIR`` and ``python -m autograder export DIR... --canvas|--moodle OUT.csv``
(:mod:`autograder.classroom`); an exercise's hints, one level at a time:
``python -m autograder hint NAME [LEVEL]`` (:mod:`autograder.hints`); in the instructor's tree, the release:
``python -m autograder release ...``, the same as ``python -m course release ...``
(:mod:`autograder.release.command`).

Exit status 0 whenever grading ran, whatever the score; 2 for usage errors.
"""

import argparse
import sys
from pathlib import Path

from autograder import sandbox

BUILTIN = ("solutions", "exercises")


def parser():
    p = argparse.ArgumentParser(prog="python -m autograder", description=(
        "Grade an implementation of the exercises. Student code runs in child processes "
        "under a time and memory limit; one failure costs one check."),
        epilog="Also: `python -m autograder hint NAME [LEVEL]` prints an exercise's hints, one level at a time "
               "(1 the approach, 2 the key identity, 3 the result); `batch` and `merge` grade a whole class.")
    p.add_argument("--impl", default="exercises",
                   help="solutions, exercises (default), or a directory laid out like exercises/")
    p.add_argument("--only", action="append", metavar="NAME",
                   help="grade only this check or exercise (e.g. damping.GavinType1); repeatable")
    p.add_argument("--json", metavar="FILE", help="also write Gradescope's results.json here")
    p.add_argument("--timeout", type=float, default=sandbox.DEFAULT_TIMEOUT,
                   help="wall-clock seconds per check (default %(default)g)")
    p.add_argument("--memory-mb", type=float, default=sandbox.DEFAULT_MEMORY_MB,
                   help="address-space limit of each child in MiB (default %(default)g)")
    p.add_argument("--workers", type=int, default=2, help="checks run in parallel (default 2)")
    p.add_argument("--set", choices=("public", "hidden", "all"), default=None, dest="which",
                   help="public checks (shipped inputs), hidden checks (fresh inputs, judged with the "
                        "reference: instructor only) or all; default: all where the reference is, else public")
    p.add_argument("--budget", type=float, default=600.0,
                   help="total seconds for the whole grading run (default %(default)g)")
    p.add_argument("--list", action="store_true", help="list the checks and their points, then exit")
    p.add_argument("--assignment", metavar="NAME", default=None,
                   help="grade this assignment of the course configuration only, with its points (default: the "
                        "tree's own in a released assignment tree, autograder/ASSIGNMENT; else the whole course)")
    p.add_argument("--config", metavar="FILE", default=None,
                   help="the course configuration (default autograder/course.toml)")
    p.add_argument("--metadata", metavar="FILE", default=None,
                   help="Gradescope's submission_metadata.json: its created_at, against the student's due date (the "
                        "latest of the assignment's, an extension in the configuration and one granted on "
                        "Gradescope), applies the assignment's late policy (needs an assignment)")
    return p


def assignment_of(args, p):
    """The :class:`autograder.course_config.Assignment` graded (None: the whole course)."""
    from autograder import course_config

    name = args.assignment or course_config.current_assignment()
    if not name:
        if args.metadata:
            p.error("--metadata: the late policy is an assignment's; give --assignment NAME")
        return None
    try:
        return course_config.load(args.config).assignment(name)
    except course_config.ConfigError as exc:
        p.error(str(exc))


def lateness_of(args, p, assignment):
    """What the late policy makes of the submission of ``args.metadata`` (None without one)."""
    if not args.metadata:
        return None
    from autograder import course_config

    try:
        submitted = course_config.gradescope_metadata(args.metadata)
    except (OSError, ValueError) as exc:  # a grade without the policy rather than no grade
        print(f"autograder: --metadata {args.metadata}: {exc}; graded without the late policy", file=sys.stderr)
        return None
    return assignment.lateness(submitted.created_at, submitted.students, due=submitted.due, granted=submitted.granted)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["batch"]:
        from autograder.classroom import batch

        return batch.main(argv[1:])
    if argv[:1] == ["export"]:
        from autograder.classroom import export

        return export.main(argv[1:])
    if argv[:1] == ["hint"]:
        from autograder import hints

        return hints.main(argv[1:])
    if argv[:1] == ["merge"]:
        from autograder.classroom import merge

        return merge.main(argv[1:])
    if argv[:1] == ["release"]:  # the instructor's tree alone holds autograder/release
        try:
            from autograder.release import command
        except ModuleNotFoundError as exc:
            if exc.name not in ("autograder.release", "autograder.release.command"):
                raise
            print("error: this tree has no release (autograder/release is the instructor's): it is a student's "
                  "tree, released from the course's repository", file=sys.stderr)
            return 2
        return command.main(argv[1:])
    p = parser()
    args = p.parse_args(argv)
    from autograder.checks import SelectionError, all_checks, select

    assignment = assignment_of(args, p)
    try:
        checks = select(assignment.checks() if assignment is not None else all_checks(), args.only)
    except SelectionError as exc:
        where = f" of assignment {assignment.name}" if assignment is not None else ""
        p.error(f"{exc}{' (among the checks' + where + ')' if where else ''}")
    if args.list:
        for check in checks:
            extra = "  (extra credit)" if assignment is not None and assignment.is_extra(check) else ""
            print(f"{check.points:>4g}  {check.name}{extra}")
        from autograder.point_grid import total

        print(f"{total(c.points for c in checks):>4g}  total")
        return 0
    lateness = lateness_of(args, p, assignment)
    if args.timeout <= 0 or args.workers < 1 or args.memory_mb <= 0 or args.budget <= 0:
        p.error("--timeout, --memory-mb, --workers and --budget must be positive")
    from autograder.grade import default_set, reference_available

    which = args.which or default_set()
    if which != "public" and not reference_available():
        p.error(f"--set {which}: the hidden checks are judged with the reference, which this tree does not "
                "have; they run on the course's side (e.g. Gradescope). Use --set public")
    impl = args.impl
    if impl not in BUILTIN:
        path = Path(impl).resolve()
        if not path.is_dir() or not (path / "__init__.py").is_file():
            p.error(f"--impl {impl!r}: expected 'solutions', 'exercises' or a directory laid out like "
                    f"exercises/ (with an __init__.py); {path} is not one")
        impl = str(path)

    from autograder import report
    from autograder.expected import ExpectedDataError
    from autograder.grade import run
    from autograder.isolation import IsolationError

    notices: list = []
    try:
        results, seconds = run(impl, args.only, timeout=args.timeout, memory_mb=args.memory_mb,
                               workers=args.workers, which=which, budget=args.budget, notices=notices,
                               assignment=assignment, checks=checks if assignment is not None else None)
    except (ExpectedDataError, IsolationError) as exc:
        print(f"autograder: {exc}", file=sys.stderr)
        return 2
    for line in notices:
        print(f"autograder: {line}", file=sys.stderr)
    if args.json:
        report.write_json(args.json, report.gradescope(results, seconds, lateness))
    title = f"assignment {assignment.name}: {assignment.title}" if assignment is not None else ""
    print(report.table(results, impl, seconds, args.workers, which, lateness, title))
    return 0


if __name__ == "__main__":
    sys.exit(main())
