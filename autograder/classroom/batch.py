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
``report.html``, ``feedback/<id>/`` (what each student gets back: ``feedback.txt`` and their
``results.json``, :mod:`autograder.classroom.student_feedback`) and a line per student in
``grading.log``.

With ``--roster`` (:mod:`autograder.classroom.roster`: the course's own columns, or Canvas' or
Gradescope's grades export as downloaded), every roster student is a row: one whom no submission
names has a record with status ``no submission`` and every check 0 (``results/<key>.json``, the key
the roster's id, else sid, login or e-mail), and each record keeps its student's roster row (the
platforms' ids and the section, for ``export``). The roster is kept with the class (``DIR/roster.csv``,
as given): a later run without ``--roster`` reads it, one with ``--roster`` replaces it.

Resumable: a student whose record exists (graded with the same set, ``--only`` and
``--assignment``, from the same files: the record keeps a hash of the exercise files it graded)
is not graded again, so a killed run restarts where it stopped, and a student whose files changed
since is graded again. ``--regrade`` grades everyone again, ``--regrade ID`` one student (by id,
sid or e-mail; repeatable).

Late work: with ``--due`` (and ``--late-per-day`` or ``--late-per-hour``, ``--cutoff-days``: an
:class:`autograder.late.LatePolicy`), each record has the submission's time (the export's
``:created_at:``, the newest file's time in a folder of uploads, or the ``submitted`` column of
``--roster``), how late it was and the penalty; the roster's ``due`` column gives a student an
extension. The instructor's overrides, kept in ``DIR/overrides.csv`` (:mod:`autograder.classroom.overrides`;
``--overrides FILE`` adds FILE's lines to it, replacing those of the same student and check), and the
penalty are applied to every record on every run, from the judge's scores kept in it: an override
survives a regrade and a plain run, and a new due date or policy needs no regrade. An override naming
no check of the assignment stops the run (exit status 2) with the close names. The marks of the written
answers (``python -m autograder.classroom.written merge``) stay in a record graded again.
``--assignment NAME`` grades that assignment of the course configuration (``autograder/course.toml``):
its checks with its points, the earlier exercises it hands out solved in place of the student's, its
due date and late policy (``--due`` and the late options override them); it labels the records and
``export``'s column.

``--shard i/n`` grades the students whose id hashes to ``i`` (1-based) of ``n``,
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
from datetime import datetime, timedelta
from pathlib import Path

from autograder import report, sandbox, submission
from autograder.classroom import gradebook, intake, marks, overrides, roster, student_feedback
from autograder.late import LatePolicy, lateness
from course.core import jsonio
from course.core.impl import REPO_ROOT

#: ``--regrade`` without an id: everyone
EVERYONE = "*"
#: the class's roster, kept in the output folder
ROSTER_FILE = "roster.csv"


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
    p.add_argument("--regrade", nargs="?", const=EVERYONE, action="append", metavar="ID",
                   help="grade again: everyone (no ID), or the student with this id, sid or e-mail (repeatable)")
    p.add_argument("--assignment", default="", metavar="NAME", help="the assignment these submissions are for "
                   "(recorded in each record; export's column name)")
    p.add_argument("--due", metavar="TIME", help="the due date, ISO 8601 (2026-10-01T23:59:00+02:00; UTC without "
                   "a zone): each record then has how late it was and the penalty")
    p.add_argument("--late-per-day", type=float, default=None, metavar="F",
                   help="the fraction of the score lost per started day late (0.1 is 10%%)")
    p.add_argument("--late-per-hour", type=float, default=None, metavar="F",
                   help="the fraction lost per started hour late")
    p.add_argument("--cutoff-days", type=float, default=None, metavar="N",
                   help="more than N days late scores 0")
    p.add_argument("--roster", metavar="CSV", help="who is in the class (each a row; 0 without a submission), "
                   "submission times, extensions: columns id, sid, email, name, submitted, due, ..., or Canvas' or "
                   "Gradescope's grades export as downloaded (autograder/classroom/roster.py)")
    p.add_argument("--overrides", metavar="CSV", help="add these overrides to the ones DIR keeps (DIR/overrides.csv, "
                   "applied on every run), replacing those of the same student and check; columns id, check, points, "
                   "reason[, twin]")
    p.add_argument("--config", metavar="FILE", default=None,
                   help="the course configuration of --assignment (default autograder/course.toml)")
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
    """True when ``path`` is a record graded the same way (set, --only, assignment, the files'
    content hash)."""
    try:
        extra = gradebook.load(path)["extra_data"]
    except ValueError:
        return False
    return all(extra.get(key) == value for key, value in grading.items())


def keys_of(sub) -> set:
    """What names a submission on the command line and in the instructor's files: its id, and each
    submitter's sid and e-mail (a group's are "; "-joined), lower case."""
    return {part.strip().lower() for key in (sub.id, sub.sid, sub.email) if key for part in key.split(";")
            if part.strip()}


def assignment_of(name: str, config=None):
    """The :class:`autograder.course_config.Assignment` ``name`` of the course configuration (``config``:
    its file, default ``autograder/course.toml``), or None for no name; ``ValueError``
    (:class:`autograder.course_config.ConfigError`) for an unknown one."""
    if not name:
        return None
    from autograder import course_config

    return course_config.load(config).assignment(name)


def assignment_settings(name: str, config=None) -> tuple:
    """``(due, policy)`` of the assignment ``name`` from the course configuration (``(None, None)``
    for no name): the command line's ``--due`` and late options override them."""
    assignment = assignment_of(name, config)
    return (None, None) if assignment is None else (assignment.due, assignment.late)


def late_settings(args) -> tuple:
    """``(due, policy)`` from the command line, else from :func:`assignment_settings`;
    ``ValueError`` for a bad time or policy."""
    due, policy = assignment_settings(args.assignment, args.config) if args.assignment else (None, None)
    if args.due:
        due = intake.parse_time(args.due)
    given = {"per_day": args.late_per_day, "per_hour": args.late_per_hour}
    if any(v is not None for v in given.values()) or args.cutoff_days is not None:
        if args.cutoff_days is not None and args.cutoff_days < 0:
            raise ValueError(f"--cutoff-days must not be negative, got {args.cutoff_days:g}")
        cutoff = timedelta(days=args.cutoff_days) if args.cutoff_days is not None else None
        policy = LatePolicy(per_day=given["per_day"] or 0.0, per_hour=given["per_hour"] or 0.0, cutoff=cutoff)
    if policy is not None and due is None:
        raise ValueError("a late policy needs a due date (--due)")
    if due is not None and policy is None:
        policy = LatePolicy()  # how late each submission was, no penalty
    return due, policy


def adjusted(data: dict, sub, due: datetime | None, policy: LatePolicy | None, found_overrides) -> dict:
    """The record ``data`` of ``sub`` with its overrides and late penalty (see gradebook.adjust)."""
    keys = (sub.id, sub.sid, sub.email)
    late = None
    if due is not None and policy is not None and sub.submitted is not None:
        named = [k for key in keys if key for k in key.split("; ")]
        late = lateness(sub.submitted, due, policy, (*named, *(k.lower() for k in named)))
    return gradebook.adjust(data, overrides.for_student(found_overrides, *keys), late,
                            due=due if late is not None else None, submitted=sub.submitted,
                            source=sub.submitted_from)


def class_roster(given, out: Path) -> roster.Roster:
    """The roster ``given`` (``--roster``; copied to ``out/roster.csv``), else the one kept there, else none;
    ``RosterError`` for a malformed one."""
    kept = out / ROSTER_FILE
    if given:
        known = roster.read(given)
        if Path(given).resolve() != kept.resolve():
            jsonio.write_text(kept, Path(given).read_text(encoding="utf-8-sig"))
        return known
    return roster.read(kept) if kept.is_file() else roster.Roster()


def students_of(known: roster.Roster, sub) -> list:
    """The roster rows that name ``sub`` (a group's submission: each member's)."""
    return known.matches(sub.id, sub.path.name, sub.sid, sub.email) if known.students else []


def absent_students(known: roster.Roster, subs, shard: int, shards: int, out: Path) -> list:
    """``(Submission, Student)`` of each roster student whom no submission names, in the part
    ``shard`` of ``shards``: the submission (its id the student's :meth:`roster.Student.key`, made
    safe, with a suffix if a submission has that id) stands for them in the gradebook."""
    present = {id(student) for sub in subs for student in students_of(known, sub)}
    taken = {sub.id for sub in subs}
    absent = []
    for student in known.students:
        if id(student) in present:
            continue
        key = intake.safe_id(student.key())
        key = key if key not in taken else f"{key}-no-submission"
        taken.add(key)
        if shard_of(key, shards) == shard:
            absent.append((intake.Submission(key, student.name or student.key(), out / "no submission",
                                             sid=student.sid, email=student.email), student))
    return absent


def _forget_absent(results_dir: Path, keep: set) -> None:
    """Remove the ``no submission`` records not in ``keep`` (a student who has since submitted, or
    who left the roster)."""
    for path in results_dir.glob("*.json"):
        try:
            extra = gradebook.load(path)["extra_data"]
        except ValueError:
            continue
        if extra.get("status") == gradebook.NO_SUBMISSION and extra["id"] not in keep:
            path.unlink()
            path.with_suffix(".txt").unlink(missing_ok=True)


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
    try:
        due, policy = late_settings(args)
    except ValueError as exc:
        p.error(str(exc))
    out = Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)
    try:
        subs = intake.read(args.submissions, unpack_to=out / "export")
        known = class_roster(args.roster, out)
        assignment = assignment_of(args.assignment, args.config)
        found_overrides = kept_overrides(out, args.overrides, assignment)
    except (intake.IntakeError, roster.RosterError, overrides.OverridesError) as exc:
        p.error(str(exc))
    subs = [roster.apply(sub, known.find(sub.id, sub.path.name, sub.sid, sub.email)) for sub in subs]
    absent = absent_students(known, subs, shard, shards, out)
    extensions = {key.lower(): s.due for s in known.students if s.due is not None
                  for key in (s.id, s.sid, s.email) if key}
    if extensions and policy is not None:
        policy = LatePolicy(policy.per_day, policy.per_hour, policy.cutoff, {**policy.extensions, **extensions})
    regrade = set(args.regrade or [])
    unknown = sorted(key for key in regrade - {EVERYONE}
                     if not any(key.lower() in keys_of(s) for s in subs))
    if unknown:
        p.error(f"--regrade {' '.join(unknown)}: no submission has this id, sid or e-mail")
    mine = [sub for sub in subs if shard_of(sub.id, shards) == shard]
    if due is not None:
        untimed = [sub.id for sub in mine if sub.submitted is None]
        if untimed:
            print(f"autograder: no submission time for {', '.join(untimed)}: no late penalty applied to them "
                  "(give a roster with a submitted column)", file=sys.stderr)
        if any(sub.submitted_from == "file time" for sub in mine):
            print("autograder: submission times are the files' modification times in the uploads; if they are not "
                  "when the students handed in, give a roster with a submitted column", file=sys.stderr)
    grading = {"set": which, "only": sorted(args.only or []), "assignment": args.assignment}
    results_dir = out / "results"
    results_dir.mkdir(exist_ok=True)
    modules = submission.exercise_modules(REPO_ROOT)
    graded_files = None if assignment is None else [f"{m}.py" for m in assignment.modules]
    where = {sub.id: submission.locate_submission(sub.path, modules, graded_files) for sub in mine}
    hashes = {sub.id: submission.content_hash(where[sub.id]) for sub in mine}

    def asked(sub) -> bool:
        return EVERYONE in regrade or bool(keys_of(sub) & {key.lower() for key in regrade})

    todo, changed = [], []
    for sub in mine:
        record_path = results_dir / f"{sub.id}.json"
        if asked(sub):
            todo.append(sub)
        elif not graded_already(record_path, {**grading, "content_hash": hashes[sub.id]}):
            todo.append(sub)
            if graded_already(record_path, grading):  # graded the same way, from other files
                changed.append(sub.id)
    log = Log(out / "grading.log")
    log(f"batch: {len(subs)} submissions, shard {shard}/{shards}: {len(mine)}, to grade: {len(todo)} "
        f"(set {which}{', only ' + ' '.join(args.only) if args.only else ''}"
        f"{', assignment ' + args.assignment if args.assignment else ''})")
    if changed:
        log(f"batch: files changed since their record, graded again: {', '.join(changed)}")
        print(f"{len(changed)} submission{'s' if len(changed) != 1 else ''} changed since graded, graded again: "
              f"{', '.join(changed)}")
    if len(todo) < len(mine):
        print(f"{len(mine) - len(todo)} of {len(mine)} submissions already graded (--regrade grades them again)")

    by_id = {sub.id: sub for sub in mine}

    def save(data: dict) -> dict:
        sub = by_id[data["extra_data"]["id"]]
        data = marks.keep(data, results_dir / f"{sub.id}.json")  # the written answers' marks stay
        data = adjusted(gradebook.with_roster(data, students_of(known, sub)), sub, due, policy, found_overrides)
        gradebook.save(results_dir, data)
        _retable(results_dir / f"{sub.id}.txt", data)
        return data

    checks = select(assignment.checks() if assignment is not None else all_checks(), args.only)
    names = [(c.name, c.exercise, c.points, False) for c in checks] if which != "hidden" else []
    names += [(c.name + HIDDEN_SUFFIX, c.exercise, c.points, True) for c in checks] if which != "public" else []
    graded, located = [], {}
    for sub in todo:
        found = where[sub.id]
        staged = out / "submissions" / sub.id
        if staged.exists():
            shutil.rmtree(staged)
        how = {**grading, "content_hash": hashes[sub.id]}
        if found.folder is None:
            save(gradebook.no_files(sub, found.message, names, how))
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
        data = gradebook.record(sub, results, seconds, located[sub.id], {**grading, "content_hash": hashes[sub.id]})
        text = report.table(results, f"{sub.id} ({sub.name})", seconds, args.jobs, which)
        try:
            (results_dir / f"{sub.id}.txt").write_text(text + "\n")
            data = save(data)
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
                       notices=notices, on_done=done, on_check=lambda index, result: bar.update(1),
                       assignment=assignment)
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
    done_ids = {sub.id for sub in graded}
    for sub in mine:  # the overrides and the late policy, on the records graded before too
        path = results_dir / f"{sub.id}.json"
        if sub.id in done_ids or not path.is_file():
            continue
        try:
            before = gradebook.load(path)
        except ValueError as exc:
            log(f"{sub.id}: {exc}")
            continue
        after = adjusted(gradebook.with_roster(before, students_of(known, sub)), sub, due, policy, found_overrides)
        if after != before:
            gradebook.save(results_dir, after)
            _retable(path.with_suffix(".txt"), after)
    for sub, student in absent:  # every roster student is a row: 0 and "no submission" where none
        data = gradebook.with_roster(gradebook.no_submission(sub, names, grading), [student])
        data = adjusted(data, sub, None, None, found_overrides)
        gradebook.save(results_dir, data)
        (results_dir / f"{sub.id}.txt").write_text(gradebook.table_with_adjustments("No submission.", data))
    _forget_absent(results_dir, {sub.id for sub, _ in absent})
    if absent:
        log(f"batch: no submission from {len(absent)} roster students: {', '.join(sub.id for sub, _ in absent)}")
        print(f"{len(absent)} roster student{'s' if len(absent) != 1 else ''} without a submission "
              f"(0 points): {', '.join(sub.id for sub, _ in absent)}")
    _check_overrides(found_overrides, mine + [sub for sub, _ in absent], results_dir, shards == 1)
    gradebook.write_table(out)
    student_feedback.write(out)
    if not args.no_report:
        from autograder.classroom import report as class_report

        class_report.write_for_this_tree(out)
    per = f", {elapsed / len(graded):.1f} s per submission" if graded else ""
    log(f"batch: graded {len(graded)} in {elapsed:.1f} s{per}")
    log.close()
    print(f"graded {len(graded)} of {len(mine)} submissions in {elapsed:.1f} s{per}; "
          f"grades in {out / 'grades.csv'}")
    return 0


def kept_overrides(out: Path, added, assignment) -> list:
    """The overrides ``out`` keeps (``out/overrides.csv``), with those of the file ``added`` (None: none)
    written into it first, replacing those of the same student and check; each checked against the
    names of the checks ``assignment`` grades (None: every check), public and hidden."""
    from autograder.checks import all_checks
    from autograder.grade import HIDDEN_SUFFIX

    checks = assignment.checks() if assignment is not None else all_checks()
    names = [name for check in checks for name in (check.name, check.name + HIDDEN_SUFFIX)]
    what = f"assignment {assignment.name}" if assignment is not None else "the course"
    path = overrides.stored(out)
    kept = overrides.read(path)
    overrides.validate(kept, names, path, what)
    if added is None:
        return kept
    new = overrides.read(added)
    overrides.validate(new, names, added, what)
    if Path(added).resolve() == path.resolve():
        return kept
    merged, count, replaced = overrides.merge(kept, new)
    overrides.write(path, merged)
    print(f"overrides: {count} added and {replaced} replaced in {path} ({len(merged)} kept, applied on every run)")
    return overrides.read(path)


def _retable(path: Path, data: dict) -> None:
    """``results/<id>.txt`` with the record's penalty and overrides on top."""
    if path.is_file():
        path.write_text(gradebook.table_with_adjustments(path.read_text(), data))


def _check_overrides(found_overrides, mine, results_dir: Path, everyone: bool) -> None:
    """Say on stderr which override names no submission (when this run sees the whole class) or a
    check its student's record does not have (a typo, or a check this run did not grade)."""
    for item in found_overrides:
        if item.check == overrides.TOTAL:
            continue
        subs = [sub for sub in mine if item.student.lower() in keys_of(sub)]
        if not subs:
            if everyone:
                print(f"autograder: overrides line {item.line}: no submission of {item.student!r}", file=sys.stderr)
            continue
        try:
            checks = {t["name"] for t in gradebook.load(results_dir / f"{subs[0].id}.json")["tests"]}
        except ValueError:
            continue
        if item.check not in checks:
            print(f"autograder: overrides line {item.line}: {item.student!r} has no check {item.check!r} "
                  "(the exact name, as in grades.csv)", file=sys.stderr)


def _bar(total: int):
    """A progress bar over the checks on stderr (quiet when it is not a terminal)."""
    from tqdm import tqdm

    return tqdm(total=total, desc="grading", unit="check", file=sys.stderr, disable=not sys.stderr.isatty(),
                dynamic_ncols=True)
