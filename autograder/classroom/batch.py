"""``python -m autograder batch SUBMISSIONS --out DIR``: grade a whole class.

SUBMISSIONS is a folder of submission folders (one per student, any layout a single
upload may have) or Gradescope's "Export Submissions" zip (:mod:`autograder.classroom.intake`).
Every submission is staged as a package (``DIR/submissions/<id>/``: the student's
exercise files, the stub for each file not sent) and graded by the same judge as a single
run (public and hidden checks where the reference is): one sandbox session for the whole
class, the expected outputs computed once, ``--jobs`` children at a time.

``DIR`` receives, per student, ``results/<id>.json`` (Gradescope's format with the
feedback, :mod:`autograder.classroom.gradebook`) and ``results/<id>.txt`` (the terminal
table), each written as soon as that student is graded; then ``grades.csv`` (atomically),
``report.html`` and a line per student in ``grading.log``.

Resumable: a student whose record exists (graded with the same set and ``--only``) is not
graded again, so a killed run restarts where it stopped; ``--regrade`` grades everyone
again. ``--shard i/n`` grades the students whose id hashes to ``i`` (1-based) of ``n``,
the same split on every machine; ``python -m autograder merge`` joins the parts.

Exit status 0 when grading ran, 2 for usage errors (a missing folder, a malformed export) or
when the grader cannot run here (stale expected data, no safe way to isolate the children).
"""

import argparse
import hashlib
import shutil
import signal
import sys
import threading
import time
from pathlib import Path

from autograder import report, sandbox, submission
from autograder.classroom import gradebook, intake
from course.core.impl import REPO_ROOT


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m autograder batch", description=__doc__.splitlines()[0])
    p.add_argument("submissions", help="a folder of submission folders, or Gradescope's export zip")
    p.add_argument("--out", required=True, metavar="DIR", help="where grades.csv, results/ and report.html go")
    p.add_argument("--jobs", "--workers", type=int, default=2, dest="jobs", help="children at a time (default 2)")
    p.add_argument("--only", action="append", metavar="NAME", help="grade only this check or exercise; repeatable")
    p.add_argument("--set", choices=("public", "hidden", "all"), default=None, dest="which",
                   help="default: all where the reference is, else public")
    p.add_argument("--timeout", type=float, default=sandbox.DEFAULT_TIMEOUT, help="seconds per check")
    p.add_argument("--memory-mb", type=float, default=sandbox.DEFAULT_MEMORY_MB, help="memory limit of a child")
    p.add_argument("--budget", type=float, default=600.0, help="seconds per submission (default %(default)g)")
    p.add_argument("--regrade", action="store_true", help="grade every submission again, even those graded")
    p.add_argument("--shard", default="1/1", metavar="I/N", help="grade the I-th of N parts (default 1/1)")
    p.add_argument("--no-report", action="store_true", help="do not write report.html")
    return p


def shard_of(sub_id: str, count: int) -> int:
    """The part (1-based) of ``count`` the id falls in: a hash, so that adding a student
    moves no one else."""
    return int.from_bytes(hashlib.sha256(sub_id.encode()).digest()[:8], "big") % count + 1


def parse_shard(text: str) -> tuple:
    try:
        index, count = (int(part) for part in text.split("/"))
    except ValueError:
        raise ValueError(f"--shard {text!r}: expected I/N, e.g. 2/4") from None
    if not 1 <= index <= count:
        raise ValueError(f"--shard {text!r}: I must be between 1 and N")
    return index, count


def graded_already(path: Path, grading: dict) -> bool:
    """True when ``path`` is a record graded the same way (set, --only)."""
    try:
        extra = gradebook.load(path)["extra_data"]
    except ValueError:
        return False
    return all(extra.get(key) == value for key, value in grading.items())


class Log:
    """``grading.log``: one line per event, flushed at once (it survives a killed run)."""

    def __init__(self, path: Path):
        self.file = open(path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()

    def __call__(self, text: str) -> None:
        self.file.write(f"{time.strftime('%Y-%m-%d %H:%M:%S')} {text}\n")
        self.file.flush()

    def close(self) -> None:
        self.file.close()


def _terminate(signum, frame):
    raise SystemExit(f"batch: stopped by signal {signum}; run the same command again to grade the rest")


def main(argv=None) -> int:
    if threading.current_thread() is threading.main_thread():  # a killed run still stops its children
        signal.signal(signal.SIGTERM, _terminate)
    p = parser()
    args = p.parse_args(argv)
    try:
        shard, shards = parse_shard(args.shard)
    except ValueError as exc:
        p.error(str(exc))
    if args.timeout <= 0 or args.jobs < 1 or args.memory_mb <= 0 or args.budget <= 0:
        p.error("--timeout, --memory-mb, --jobs and --budget must be positive")
    from autograder.checks import SelectionError, all_checks, select
    from autograder.grade import HIDDEN_SUFFIX, default_set, grade_many, reference_available

    which = args.which or default_set()
    if which != "public" and not reference_available():
        p.error(f"--set {which}: the hidden checks need the reference, which this tree does not have")
    try:
        select(all_checks(), args.only)
    except SelectionError as exc:
        p.error(str(exc))
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    try:
        subs = intake.read(args.submissions, unpack_to=out / "export")
    except intake.IntakeError as exc:
        p.error(str(exc))
    mine = [sub for sub in subs if shard_of(sub.id, shards) == shard]
    grading = {"set": which, "only": sorted(args.only or [])}
    results_dir = out / "results"
    results_dir.mkdir(exist_ok=True)
    todo = [sub for sub in mine if args.regrade or not graded_already(results_dir / f"{sub.id}.json", grading)]
    log = Log(out / "grading.log")
    log(f"batch: {len(subs)} submissions, shard {shard}/{shards}: {len(mine)}, to grade: {len(todo)} "
        f"(set {which}{', only ' + ' '.join(args.only) if args.only else ''})")
    if len(todo) < len(mine):
        print(f"{len(mine) - len(todo)} of {len(mine)} submissions already graded (--regrade grades them again)")

    modules = submission.exercise_modules(REPO_ROOT)
    checks = select(all_checks(), args.only)
    names = [(c.name, c.exercise, c.points, False) for c in checks] if which != "hidden" else []
    names += [(c.name + HIDDEN_SUFFIX, c.exercise, c.points, True) for c in checks] if which != "public" else []
    graded, located = [], {}
    for sub in todo:
        found = submission.locate_submission(sub.path, modules)
        staged = out / "submissions" / sub.id
        if staged.exists():
            shutil.rmtree(staged)
        if found.folder is None:
            gradebook.save(results_dir, gradebook.no_files(sub, found.message, names, grading))
            log(f"{sub.id}: no files ({found.message.splitlines()[0]})")
            continue
        submission.stage_submission(found, REPO_ROOT, staged)
        graded.append(sub)
        located[sub.id] = found.message

    start = time.perf_counter()
    bar = _bar(len(graded) * len(names))

    def done(index, results):
        sub = graded[index]
        seconds = sum(r.seconds for r in results)
        data = gradebook.record(sub, results, seconds, located[sub.id], grading)
        text = report.table(results, f"{sub.id} ({sub.name})", seconds, args.jobs, which)
        try:
            (results_dir / f"{sub.id}.txt").write_text(text + "\n")
            gradebook.save(results_dir, data)
        except OSError as exc:  # e.g. a full disk: this student is graded again by the next run
            log(f"{sub.id}: graded, but the record could not be written ({exc}); run again to grade it")
            print(f"autograder: {sub.id}: the record could not be written ({exc})", file=sys.stderr)
            return
        log(f"{sub.id}: {data['extra_data']['status']}, {data['score']:g} points, {seconds:.1f} s")

    if graded:
        from autograder.expected import ExpectedDataError
        from autograder.isolation import IsolationError

        notices: list = []
        try:
            grade_many([str(out / "submissions" / sub.id) for sub in graded], args.only, timeout=args.timeout,
                       memory_mb=args.memory_mb, workers=args.jobs, which=which, budget=args.budget,
                       notices=notices, on_done=done, on_check=lambda index, result: bar.update(1))
        except (ExpectedDataError, IsolationError) as exc:  # the grader cannot run here: nobody was graded
            bar.close()
            log(f"batch: could not grade ({exc})")
            log.close()
            print(f"autograder: {exc}", file=sys.stderr)
            return 2
        for line in notices:
            print(f"autograder: {line}", file=sys.stderr)
    bar.close()
    elapsed = time.perf_counter() - start
    gradebook.write_table(out)
    if not args.no_report:
        from autograder.classroom import report as class_report

        class_report.write_for_this_tree(out)
    per = f", {elapsed / len(graded):.1f} s per submission" if graded else ""
    log(f"batch: graded {len(graded)} in {elapsed:.1f} s{per}")
    log.close()
    print(f"graded {len(graded)} of {len(mine)} submissions in {elapsed:.1f} s{per}; "
          f"grades in {out / 'grades.csv'}")
    return 0


def _bar(total: int):
    """A progress bar over the checks on stderr (quiet when it is not a terminal)."""
    from tqdm import tqdm

    return tqdm(total=total, desc="grading", unit="check", file=sys.stderr, disable=not sys.stderr.isatty(),
                dynamic_ncols=True)
