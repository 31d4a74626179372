"""``python -m autograder.classroom.written export|rubric|collect|marks-template|merge``: written answers, graded.

* ``export --assignment NAME --out PATH``: the answer sheet of the assignment's written questions
  (:mod:`autograder.classroom.questions`), ``answers.md``, for the students to fill and hand in with
  their code (PATH a file, or a folder such as the assignment's student tree: PATH/answers.md). It
  holds the questions and their points, nothing of the reference answers or the rubric's items.
* ``rubric --assignment NAME --out FILE``: the assignment's rubric (its file's, or the default) as
  a TOML file to edit into ``solutions/rubrics/NAME.toml`` (:mod:`autograder.classroom.rubric`).
* ``collect --assignment NAME SUBMISSIONS --out FOLDER``: the students' filled sheets
  (:mod:`autograder.classroom.answers`; SUBMISSIONS as ``batch`` reads them), one document per
  question with every student's answer and the rubric's items, to mark a question at a time; a
  submission without a sheet, or with changed headings, is named on stderr.
* ``marks-template --assignment NAME --class DIR --out FILE``: a marks CSV with a row per graded
  student and question, to fill (:mod:`autograder.classroom.marks`).
* ``merge --assignment NAME --class DIR [--marks FILE]``: check the marks (FILE, copied to
  ``DIR/written.csv``, where the class keeps them; default that file) and put them into the records:
  each question a test ``written: <id>`` in the total, then ``grades.csv`` and ``report.html`` again.
  ``export``'s Canvas and Moodle files then carry the written points in the assignment's column.
  ``batch`` keeps them when it grades a student again.

Exit status 0, or 2 with a message naming the file, the line and the field.
"""

import argparse
import shutil
import sys
from pathlib import Path

from autograder.classroom import answers, gradebook, intake, marks, questions, rubric
from course.core import jsonio


def _assignment(name: str):
    from autograder import course_config

    return course_config.load().assignment(name)


def _records(folder: Path, name: str) -> list:
    results = Path(folder) / "results"
    if not results.is_dir():
        raise ValueError(f"{folder}: no results/ folder (not the --out of `python -m autograder batch`)")
    records = gradebook.load_all(results)
    if not records:
        raise ValueError(f"{results}: no record: grade the class with `python -m autograder batch` first")
    other = sorted({str(r["extra_data"].get("assignment") or "") for r in records} - {name, ""})
    if other:
        raise ValueError(f"{results}: records of assignment {', '.join(other)}, not {name}")
    return records


def export(assignment, out: Path) -> Path:
    """Write the answer sheet of ``assignment`` to ``out`` (a folder: ``out/answers.md``)."""
    found = questions.of_assignment(assignment)
    points = {qid: r.points for qid, r in rubric.read(assignment.name, found).items()}
    path = Path(out) / "answers.md" if Path(out).is_dir() else Path(out)
    return jsonio.write_text(path, questions.sheet(assignment, found, points))


def collect(assignment, submissions: Path, out: Path) -> answers.Gathered:
    """Write one document per question of ``assignment`` into ``out`` from the sheets in ``submissions``."""
    asked = questions.of_assignment(assignment)
    out = Path(out)
    gathered = answers.gather(intake.read(submissions, unpack_to=out / "export"), asked)
    for name, text in answers.documents(asked, rubric.read(assignment.name, asked), gathered).items():
        jsonio.write_text(out / name, text)
    return gathered


def merge(assignment, folder: Path, marks_file: Path | None = None) -> dict:
    """Put the marks into the records of the class in ``folder``; returns counts."""
    folder = Path(folder)
    found = questions.of_assignment(assignment)
    rubrics = rubric.read(assignment.name, found)
    records = _records(folder, assignment.name)
    kept = folder / marks.FILE
    source = Path(marks_file) if marks_file else kept
    if not source.is_file():
        raise ValueError(f"{source}: no marks file (`marks-template` writes one to fill)")
    given = marks.read(source, rubrics, records)
    if source.resolve() != kept.resolve():
        shutil.copyfile(source, kept)
    changed = 0
    for record in records:
        after = marks.readjust(marks.with_marks(record, marks.tests(record, rubrics, given)))
        if after != record:
            gradebook.save(folder / "results", after)
            changed += 1
    gradebook.write_table(folder)
    marked = sum(m.points is not None for m in given)
    return {"records": len(records), "changed": changed, "marked": marked,
            "unmarked": len(records) * len(rubrics) - marked}


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m autograder.classroom.written", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    for name, text in (("export", "the answer sheet students fill (answers.md)"),
                       ("rubric", "the assignment's rubric as a TOML file to edit"),
                       ("collect", "the students' sheets, one document per question, to mark"),
                       ("marks-template", "a marks CSV to fill, a row per student and question"),
                       ("merge", "the marks into the records, grades.csv and the report")):
        command = sub.add_parser(name, help=text, description=text)
        command.add_argument("--assignment", required=True, metavar="NAME", help="the assignment (course.toml)")
        if name == "collect":
            command.add_argument("submissions", help="a folder of submission folders, or Gradescope's export zip")
        if name in ("marks-template", "merge"):
            command.add_argument("--class", dest="folder", required=True, metavar="DIR",
                                 help="the --out folder of `python -m autograder batch`")
        if name == "merge":
            command.add_argument("--marks", metavar="FILE", help=f"the marks (default DIR/{marks.FILE}); "
                                 f"copied to DIR/{marks.FILE}")
            command.add_argument("--no-report", action="store_true", help="do not write report.html again")
        else:
            where = {"export": "the file to write (or a folder: PATH/answers.md)",
                     "collect": "the folder to write the documents into"}
            command.add_argument("--out", required=True, metavar="PATH", help=where.get(name, "the file to write"))
    return p


def main(argv=None) -> int:
    p = parser()
    args = p.parse_args(argv)
    try:
        assignment = _assignment(args.assignment)
        if args.command == "export":
            path = export(assignment, Path(args.out))
            print(f"wrote {path}: {len(questions.of_assignment(assignment))} questions of {assignment.name}")
        elif args.command == "rubric":
            found = questions.of_assignment(assignment)
            path = jsonio.write_text(Path(args.out), rubric.text_of(assignment.name, found,
                                                                    rubric.read(assignment.name, found)))
            print(f"wrote {path}: edit it into {rubric.path_of(assignment.name)}")
        elif args.command == "collect":
            gathered = collect(assignment, Path(args.submissions), Path(args.out))
            for line in gathered.problems:
                print(f"written: {line}", file=sys.stderr)
            print(f"wrote {args.out}: {len(questions.of_assignment(assignment))} questions, the sheets of "
                  f"{len(gathered.answers)} of {len(gathered.names)} submissions")
        elif args.command == "marks-template":
            found = questions.of_assignment(assignment)
            records = _records(Path(args.folder), assignment.name)
            path = jsonio.write_text(Path(args.out), marks.template(records, found))
            print(f"wrote {path}: {len(records)} students x {len(found)} questions to mark")
        else:
            counts = merge(assignment, Path(args.folder), Path(args.marks) if args.marks else None)
            if not args.no_report:
                from autograder.classroom import report

                report.write_for_this_tree(Path(args.folder))
            print(f"merged {counts['marked']} marks into {counts['records']} records ({counts['changed']} changed); "
                  f"{counts['unmarked']} answers not marked yet; grades in {Path(args.folder) / 'grades.csv'}")
    except (ValueError, OSError) as exc:  # ConfigError, QuestionsError, RubricError, MarksError, IntakeError
        print(f"written: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
