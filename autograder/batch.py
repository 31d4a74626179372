"""``python -m autograder batch FOLDER --out DIR``: grade every implementation in ``FOLDER`` in
one run.

Each subfolder of ``FOLDER`` with an ``__init__.py`` (laid out like ``exercises/``) is one
implementation. The expected outputs are computed once, and one sandbox session runs the
children of all of them, ``--workers`` at a time, each check in a child of its own as in a
single grading run. ``DIR`` receives ``NAME.json`` (Gradescope's ``results.json``) and
``NAME.txt`` (the terminal table) per implementation. Exit status 0 when grading ran, 2 for
usage errors.
"""

import argparse
import sys
import time
from pathlib import Path

from autograder import sandbox


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m autograder batch", description=__doc__.splitlines()[0])
    p.add_argument("folder", help="a folder of implementations, one subfolder (with an __init__.py) each")
    p.add_argument("--out", required=True, metavar="DIR", help="where NAME.json and NAME.txt are written")
    p.add_argument("--only", action="append", metavar="NAME", help="grade only this check or exercise; repeatable")
    p.add_argument("--timeout", type=float, default=sandbox.DEFAULT_TIMEOUT, help="wall-clock seconds per check")
    p.add_argument("--memory-mb", type=float, default=sandbox.DEFAULT_MEMORY_MB, help="memory limit of a child")
    p.add_argument("--workers", type=int, default=2, help="children at a time (default %(default)s)")
    p.add_argument("--set", choices=("public", "hidden", "all"), default=None, dest="which")
    p.add_argument("--budget", type=float, default=600.0, help="seconds per implementation (default %(default)g)")
    return p


def implementations(folder: Path) -> list:
    """The subfolders of ``folder`` that are packages, by name."""
    return sorted(p for p in folder.iterdir() if p.is_dir() and (p / "__init__.py").is_file())


def main(argv=None) -> int:
    p = parser()
    args = p.parse_args(argv)
    folder = Path(args.folder).resolve()
    if not folder.is_dir():
        p.error(f"{folder} is not a folder")
    impls = implementations(folder)
    if not impls:
        p.error(f"{folder} holds no implementation (a subfolder with an __init__.py)")
    if args.timeout <= 0 or args.workers < 1 or args.memory_mb <= 0 or args.budget <= 0:
        p.error("--timeout, --memory-mb, --workers and --budget must be positive")
    from autograder import report
    from autograder.grade import default_set, grade_many, reference_available

    which = args.which or default_set()
    if which != "public" and not reference_available():
        p.error(f"--set {which}: the hidden checks need the reference, which this tree does not have")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    notices: list = []
    start = time.perf_counter()
    every = grade_many([str(path) for path in impls], args.only, timeout=args.timeout, memory_mb=args.memory_mb,
                       workers=args.workers, which=which, budget=args.budget, notices=notices)
    seconds = (time.perf_counter() - start) / len(impls)
    for line in notices:
        print(f"autograder: {line}", file=sys.stderr)
    for path, results in zip(impls, every):
        report.write_json(out / f"{path.name}.json", report.gradescope(results, seconds))
        (out / f"{path.name}.txt").write_text(report.table(results, str(path), seconds, args.workers, which) + "\n")
    print(f"graded {len(impls)} implementations in {time.perf_counter() - start:.1f} s; results in {out}")
    return 0
