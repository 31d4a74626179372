"""``python -m course release``: ``exercises/`` from ``solutions/``, the public checks' data, the student
tree (``--student DIR``) and the Gradescope zip (``--gradescope FILE.zip``).

The framework's command line offers it through the entry point ``release`` of the group
``course.commands`` (``pyproject.toml``; :mod:`course.app.command_plugins`), which names
:func:`add_parser`; ``python -m autograder release`` (:func:`main`) runs it without that registration.
Both exist in the instructor's tree only: the student tree leaves ``autograder/release`` out
(``autograder.release.stubs.INSTRUCTOR_ONLY``) and its ``pyproject.toml`` registers no ``release``."""

import argparse
import sys
from pathlib import Path

HELP = "regenerate exercises/ from solutions/"


def add_parser(sub) -> None:
    """Add the ``release`` subcommand to the command line's subparsers ``sub`` (the entry point)."""
    add_arguments(sub.add_parser("release", help=HELP))


def main(argv=None) -> int:
    """``python -m autograder release ...``: the same command, with the same arguments."""
    parser = argparse.ArgumentParser(prog="python -m autograder release", description=HELP)
    add_arguments(parser)
    args = parser.parse_args(argv)
    return int(args.func(args) or 0)


def add_arguments(release: argparse.ArgumentParser) -> None:
    """The ``release`` command's arguments, on ``release`` (a subparser or a parser of its own)."""
    release.add_argument("--check", action="store_true",
                         help="only check: exit 1 and list the stale files when exercises/ is out of date")
    release.add_argument("--student", metavar="DIR", help="also write a student tree (no solutions/) to DIR")
    release.add_argument("--root", metavar="DIR", default=None,
                         help="repository holding solutions/ and exercises/ (default: this checkout)")
    release.add_argument("--gradescope", metavar="FILE.zip", default=None,
                         help="also write the Gradescope autograder zip (setup.sh, run_autograder, the grader "
                              "and the reference) to FILE.zip; with --check, only when nothing is stale")
    release.add_argument("--hints", type=int, choices=(0, 1, 2, 3), default=None,
                         help="hint levels printed into the stubs' docstrings: 0 none, 1 the approach, 2 and the "
                              "key identity, 3 and the result (the formulas); default: the level exercises/ records "
                              "(0 when none). Students get every level from `python -m autograder hint NAME LEVEL`")
    release.add_argument("--hidden-seed", type=int, default=None,
                         help="seed of the hidden checks' inputs in the Gradescope zip (default: a random one)")
    release.add_argument("--assignment", metavar="NAME", default=None,
                         help="hand out one assignment of the course configuration: --student and --gradescope "
                              "then hold and grade NAME only (its stubs, the files it gives solved, its points, "
                              "visibilities and late policy); without it, the whole course")
    release.add_argument("--config", metavar="FILE", default=None,
                         help="the course configuration (default: autograder/course.toml of the repository)")
    release.add_argument("--force", action="store_true",
                         help="with --assignment NAME --student DIR: write the tree even before NAME's "
                              "release_after when it hands out solved (reference) code")
    release.set_defaults(func=run)


def run(args) -> int:
    """``release``: regenerate (or ``--check``) ``exercises/`` and the public checks' data; optionally
    write a student tree and the Gradescope zip, of the whole course or of one ``--assignment``."""
    from autograder.release.stubs import release
    from course.core.impl import REPO_ROOT

    root = Path(args.root) if args.root else REPO_ROOT
    if not (root / "solutions").is_dir():
        print(f"error: {root} has no solutions/ folder to release from", file=sys.stderr)
        return 2
    assignment = course = None
    if args.assignment:
        from autograder.course_config import ConfigError, load

        try:
            course = load(args.config or root / "autograder" / "course.toml")
            assignment = course.assignment(args.assignment)
        except ConfigError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        if args.student and not args.check:
            from autograder.release.release_date import early_release

            early = early_release(course, assignment)
            if early and not args.force:
                print(f"error: {early}; give --force to release it anyway", file=sys.stderr)
                return 2
            if early:
                print(f"warning: {early} (--force)", file=sys.stderr)
    data_stale = []
    if root.resolve() == REPO_ROOT.resolve():  # the public checks' data, before a student tree copies it
        from autograder.oracle import release_expected

        data_stale = [f"autograder/{rel}" for rel in release_expected(check=args.check)]
    stale = release(check=args.check, student_dir=None if assignment else args.student, root=root, hints=args.hints)
    overlay = None
    if assignment is not None:
        from autograder.release import assignment as handout
        from autograder.release.stubs import ReleaseError, hints_level, render

        stubs = render(root / "solutions", hints_level(root) if args.hints is None else args.hints)
        overlay = handout.bundle_overlay(course, assignment, stubs, root)
        if args.student and not args.check:
            try:
                handout.write_student_tree(args.student, course, assignment, stubs, root)
            except ReleaseError as exc:
                print(f"error: {exc}", file=sys.stderr)
                return 2
    if args.check:
        if data_stale:
            print("the public checks' data is out of date; run `python -m course release`. Stale files:")
            print("\n".join(f"  {rel}" for rel in data_stale))
        if stale:
            print("exercises/ is out of date with solutions/; run `python -m course release`. Stale files:")
            for rel in stale:
                print(f"  exercises/{rel}")
            return 1
        if data_stale:
            return 1
        print("exercises/ is up to date")
        return _write_gradescope(args.gradescope, root, args.hidden_seed, overlay)
    print("rewrote exercises/: " + ", ".join(stale) if stale else "exercises/ was already up to date")
    if data_stale:
        print("rewrote the public checks' data: " + ", ".join(data_stale))
    what = f" of assignment {assignment.name}" if assignment is not None else ""
    if args.student:
        print(f"wrote the student tree{what} to {args.student}")
    return _write_gradescope(args.gradescope, root, args.hidden_seed, overlay, what)


def _write_gradescope(target, root, hidden_seed=None, overlay=None, what="") -> int:
    """``release --gradescope FILE.zip``: the autograder bundle (``autograder.release.gradescope``)."""
    if not target:
        return 0
    from autograder.release.gradescope import BundleError, build_bundle

    try:
        bundle = build_bundle(target, root, hidden_seed, overlay)
    except BundleError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote the Gradescope autograder{what} to {bundle.path} ({bundle.size / 2**20:.2f} MiB, "
          f"{len(bundle.members)} files); upload it as the assignment's autograder zip")
    return 0
