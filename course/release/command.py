"""``python -m course release``: ``exercises/`` from ``solutions/``, the public checks' data, the student
tree (``--student DIR``) and the Gradescope zip (``--gradescope FILE.zip``). The command line
(``course.app.cli``) offers it where this package is, in the instructor's tree; the student tree
leaves ``course/release`` out (``course.release.stubs.INSTRUCTOR_ONLY``)."""

import sys
from pathlib import Path


def add_parser(sub) -> None:
    """Add the ``release`` subcommand to the command line's subparsers ``sub``."""
    release = sub.add_parser("release", help="regenerate exercises/ from solutions/")
    release.add_argument("--check", action="store_true",
                         help="only check: exit 1 and list the stale files when exercises/ is out of date")
    release.add_argument("--student", metavar="DIR", help="also write a student tree (no solutions/) to DIR")
    release.add_argument("--root", metavar="DIR", default=None,
                         help="repository holding solutions/ and exercises/ (default: this checkout)")
    release.add_argument("--gradescope", metavar="FILE.zip", default=None,
                         help="also write the Gradescope autograder zip (setup.sh, run_autograder, the grader "
                              "and the reference) to FILE.zip; with --check, only when nothing is stale")
    release.add_argument("--hidden-seed", type=int, default=None,
                         help="seed of the hidden checks' inputs in the Gradescope zip (default: a random one)")
    release.set_defaults(func=run)


def run(args) -> int:
    """``release``: regenerate (or ``--check``) ``exercises/`` and the public checks' data; optionally
    write a student tree and the Gradescope zip."""
    from course.core.impl import REPO_ROOT
    from course.release.stubs import release

    root = Path(args.root) if args.root else REPO_ROOT
    if not (root / "solutions").is_dir():
        print(f"error: {root} has no solutions/ folder to release from", file=sys.stderr)
        return 2
    data_stale = []
    if root.resolve() == REPO_ROOT.resolve():  # the public checks' data, before a student tree copies it
        from autograder.oracle import release_expected

        data_stale = [f"autograder/{rel}" for rel in release_expected(check=args.check)]
    stale = release(check=args.check, student_dir=args.student, root=root)
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
        return _write_gradescope(args.gradescope, root, args.hidden_seed)
    print("rewrote exercises/: " + ", ".join(stale) if stale else "exercises/ was already up to date")
    if data_stale:
        print("rewrote the public checks' data: " + ", ".join(data_stale))
    if args.student:
        print(f"wrote the student tree to {args.student}")
    return _write_gradescope(args.gradescope, root, args.hidden_seed)


def _write_gradescope(target, root, hidden_seed=None) -> int:
    """``release --gradescope FILE.zip``: the autograder bundle (``course.release.gradescope``)."""
    if not target:
        return 0
    from course.release.gradescope import BundleError, build_bundle

    try:
        bundle = build_bundle(target, root, hidden_seed)
    except BundleError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"wrote the Gradescope autograder to {bundle.path} ({bundle.size / 2**20:.2f} MiB, "
          f"{len(bundle.members)} files); upload it as the assignment's autograder zip")
    return 0
