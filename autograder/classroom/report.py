"""The class report, ``DIR/report.html``, from what ``python -m autograder batch`` leaves in ``DIR``.

One static page (no server, no external files; the histogram is an embedded PNG): the
headline (students, mean and median total, the points available), the histogram of the
totals, the share of the class with full marks on each check (hardest first), the known
mistakes the class made per exercise (a student counts once per mistake sentence), the
submissions that timed out, crashed or sent no files, the pairs of submissions whose
code is unusually similar, and the files that reproduce the reference's solution (a leaked
solution, handed in by one student or several; :mod:`autograder.classroom.similarity`). It reads
``DIR/results/<id>.json`` and ``DIR/submissions/<id>/`` as data and text only.

``python -m autograder.classroom.report DIR [--stubs exercises] [--reference solutions]``
writes the report and prints its path.
"""

import argparse
import base64
import datetime
import html
import io
import json
import statistics
from dataclasses import dataclass
from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from autograder import point_grid
from autograder.classroom import similarity
from autograder.report import points

#: a check scored within this of its maximum has full marks
TOLERANCE = 1e-9
PROBLEMS = ("timed out", "crashed", "no files")
#: lines shown per side for one similar pair
MAX_LINES = 120
STYLE = """
body { font-family: sans-serif; max-width: 75em; margin: 1em auto; padding: 0 1em; }
table { border-collapse: collapse; margin: 0.5em 0 1.5em; }
th, td { border: 1px solid #bbb; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }
th { background: #eee; }
td.num { text-align: right; }
pre { margin: 0; font-size: 85%; }
.note { color: #555; }
"""


@dataclass
class Student:
    """One student's results: id, name, status, total, maximum and the tests as recorded."""

    sid: str
    name: str
    status: str
    score: float
    max_score: float
    tests: list


def _e(value) -> str:
    return html.escape(str(value), quote=True)


def load_students(out_dir: Path) -> tuple:
    """The students of ``out_dir/results/*.json`` by id, and notes on the files that do not read."""
    students, notes = [], []
    for path in sorted((Path(out_dir) / "results").glob("*.json")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
            extra = data.get("extra_data") or {}
            tests = [t for t in data.get("tests") or [] if isinstance(t, dict)]
            students.append(Student(
                sid=str(extra.get("id") or path.stem), name=str(extra.get("name") or ""),
                status=str(extra.get("status") or "ok"), score=float(data.get("score") or 0.0),
                max_score=point_grid.total(t.get("max_score") or 0 for t in tests), tests=tests))
        except (ValueError, TypeError, AttributeError, OSError) as exc:
            notes.append(f"{path.name}: not read ({exc})")
    return students, notes


def _who(student: Student) -> str:
    return f"{student.sid} ({student.name})" if student.name else student.sid


def _test_extra(test: dict) -> dict:
    extra = test.get("extra_data")
    return extra if isinstance(extra, dict) else {}


def _exercise(test: dict) -> str:
    name = str(test.get("name", ""))
    return str(_test_extra(test).get("exercise") or name.split(":")[0].split(".")[0])


def _hidden(test: dict) -> bool:
    return bool(_test_extra(test).get("hidden", test.get("visibility") == "after_published"))


def _full(test: dict) -> bool:
    return float(test.get("score") or 0.0) >= float(test.get("max_score") or 0.0) - TOLERANCE


def histogram_png(totals: list, maximum: float) -> str:
    """The histogram of the totals as a base64 PNG (a Figure of its own: no pyplot state)."""
    fig = Figure(figsize=(7, 3), dpi=100)
    ax = fig.add_subplot()
    top = max([maximum, *totals, 1.0])
    ax.hist(totals, bins=min(20, max(5, len(totals))), range=(0.0, top), color="#4878a8", edgecolor="white")
    ax.set_xlabel(f"total points (out of {points(maximum)})")
    ax.set_ylabel("students")
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlim(0.0, top)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    return base64.b64encode(buffer.getvalue()).decode("ascii")


def pass_rates(students: list) -> list:
    """Per check ``(name, exercise, hidden, students with full marks, class size)``, hardest first.
    A student without the check (no files, nothing graded) does not have full marks."""
    order: dict = {}
    for student in students:
        for test in student.tests:
            name = str(test.get("name", ""))
            if name not in order:
                order[name] = [len(order), _exercise(test), _hidden(test), 0]
            if _full(test):
                order[name][3] += 1
    rows = [(name, exercise, hidden, full, len(students)) for name, (_, exercise, hidden, full) in order.items()]
    return sorted(rows, key=lambda r: (r[3] / max(r[4], 1), order[r[0]][0]))


def mistakes(students: list) -> dict:
    """``{exercise: {mistake sentence: [students]}}``, a student once per sentence."""
    found: dict = {}
    for student in students:
        for test in student.tests:
            sentence = _test_extra(test).get("mistake")
            if sentence:
                who = found.setdefault(_exercise(test), {}).setdefault(str(sentence), [])
                if student not in who:
                    who.append(student)
    return found


def problems(students: list) -> list:
    """``(student, checks concerned)`` for each submission that timed out, crashed, sent no
    files, or has a check that did not run to the end."""
    rows = []
    for student in students:
        bad = [(str(t.get("name", "")), str(_test_extra(t).get("status"))) for t in student.tests
               if _test_extra(t).get("status") not in (None, "ok")]
        if student.status in PROBLEMS or bad:
            rows.append((student, bad))
    return rows


def _section(ident: str, title: str, body: str) -> str:
    return f'<h2 id="{ident}">{_e(title)}</h2>\n{body}\n'


def _headline(students: list) -> str:
    totals = [s.score for s in students]
    maximum = max((s.max_score for s in students), default=0.0)
    if not totals:
        return "<p>No results were found.</p>"
    mean, median = statistics.fmean(totals), statistics.median(totals)
    statuses = {status: sum(1 for s in students if s.status == status) for status in PROBLEMS}
    extra = ", ".join(f"{n} {status}" for status, n in statuses.items() if n)
    return (f"<p><strong>{len(students)} students</strong>; mean total {mean:.1f}, median {median:.1f}, "
            f"out of {points(maximum)} points; lowest {points(min(totals))}, highest {points(max(totals))}"
            f"{'; ' + _e(extra) if extra else ''}.</p>\n"
            f'<p><img alt="histogram of the totals" src="data:image/png;base64,'
            f'{histogram_png(totals, maximum)}"></p>')


def _table(intro: str, headers, rows: str) -> str:
    """An introducing sentence, then a table with ``headers`` over the ``rows`` (HTML ``<tr>`` lines)."""
    head = "".join(f"<th>{_e(h)}</th>" for h in headers)
    return f"<p>{intro}</p>\n<table><tr>{head}</tr>\n{rows}</table>"


def _checks_table(students: list) -> str:
    rows = pass_rates(students)
    if not rows:
        return "<p>No checks were graded.</p>"
    body = "".join(f"<tr><td>{_e(name)}</td><td>{_e(exercise)}</td><td>{'hidden' if hidden else 'public'}</td>"
                   f'<td>{full} / {size}</td><td class="num">{100.0 * full / max(size, 1):.0f}%</td></tr>\n'
                   for name, exercise, hidden, full, size in rows)
    return _table("The share of the class with full marks on each check, hardest first. Hidden checks run on "
                  "inputs the students did not see.", ("Check", "Exercise", "Inputs", "Full marks", "Share"), body)


def _mistakes_table(students: list) -> str:
    found = mistakes(students)
    if not found:
        return "<p>No output matched a known mistake.</p>"
    body = ""
    for exercise in sorted(found):
        for sentence, who in sorted(found[exercise].items(), key=lambda kv: (-len(kv[1]), kv[0])):
            body += (f"<tr><td>{_e(exercise)}</td><td>{_e(sentence)}</td><td>{len(who)}</td>"
                     f"<td>{_e(', '.join(_who(s) for s in who))}</td></tr>\n")
    return _table("The known mistakes whose outputs the class's matched (a student counts once per mistake).",
                  ("Exercise", "Likely cause", "Students", "Who"), body)


def _problems_table(students: list) -> str:
    rows = problems(students)
    if not rows:
        return "<p>Every submission ran to the end.</p>"
    body = ""
    for student, bad in rows:
        kinds = {status for _, status in bad}
        if not student.tests:
            concerned = "no exercise file was sent: nothing was graded"
        elif len(bad) == len(student.tests) and len(kinds) == 1:
            concerned = f"all {len(bad)} checks: {kinds.pop()}"
        else:
            concerned = "; ".join(f"{name} ({status})" for name, status in bad) or "none recorded"
        body += (f"<tr><td>{_e(_who(student))}</td><td>{_e(student.status)}</td>"
                 f'<td class="num">{points(student.score)}</td><td>{_e(concerned)}</td></tr>\n')
    return _table("The submissions that timed out, crashed or sent no files, and the checks that did not run "
                  "to the end.", ("Student", "Status", "Total", "Checks concerned"), body)


def _shown_lines(path: Path, ranges: list) -> str:
    """The lines of ``ranges`` in ``path``, numbered and escaped; gaps of up to 3 lines are shown."""
    try:
        lines = path.read_bytes().decode("utf-8", errors="replace").splitlines()
    except OSError as exc:
        return _e(f"({path.name} not read: {exc})")
    groups: list = []
    for first, last in ranges:
        if groups and first <= groups[-1][1] + 4:
            groups[-1][1] = max(groups[-1][1], last)
        else:
            groups.append([first, last])
    out: list = []
    shown = 0
    for first, last in groups:
        if out:
            out.append("     ...")
        for number in range(first, min(last, len(lines)) + 1):
            if shown == MAX_LINES:
                out.append(f"     ... (shown: the first {MAX_LINES} lines)")
                return _e("\n".join(out))
            out.append(f"{number:4d}  {lines[number - 1]}")
            shown += 1
    return _e("\n".join(out))


def _compare(out_dir: Path, stubs_dir: Path, reference_dir):
    """The class's :class:`similarity.Comparison`, or the folder that is missing (a Path)."""
    submissions = Path(out_dir) / "submissions"
    if not submissions.is_dir() or not Path(stubs_dir).is_dir():
        return submissions if not submissions.is_dir() else Path(stubs_dir)
    return similarity.compare_class(submissions, stubs_dir, reference_dir)


def _similar_section(out_dir: Path, students: list, stubs_dir: Path, reference_dir, found) -> str:
    names = {s.sid: s for s in students}
    label = lambda sid: _who(names[sid]) if sid in names else sid
    discounted = ("the shipped stubs (docstrings, signatures, hints), the reference solution's code (a correct "
                  "answer copied from the reference is not evidence that two students copied each other)"
                  if reference_dir is not None else
                  "the shipped stubs (docstrings, signatures, hints); no reference solution was given, so only "
                  "the class-common code below stands in for it")
    intro = (f"<p>Pairs of students whose code for one exercise file is unusually similar. Discounted first: "
             f"{_e(discounted)}, and the code found in at least {similarity.COMMON_FRACTION:.0%} of the written "
             f"submissions of a file (the short lines many correct students write alike). Comments, docstrings, "
             f"blank lines and the names of variables are ignored. A pair is listed when it shares at least "
             f"{similarity.MIN_CONTAINMENT:.0%} of the smaller submission's remaining {similarity.NGRAM}-token "
             f"sequences, at least {similarity.MIN_SHARED} of them, and stands out from the other pairs of that "
             f"file (above the median by {similarity.OUTLIER_MADS:g} scaled MADs). Files left as the stub are not "
             f"compared.</p>\n<p><strong>Similarity is a prompt to look at two submissions, not a verdict.</strong>"
             f"</p>\n")
    submissions = Path(out_dir) / "submissions"
    if isinstance(found, Path):
        return intro + f'<p class="note">Not compared: {_e(found)} is not a folder.</p>'
    parts = [intro]
    if found.pairs:
        rows = "".join(f"<tr><td>{_e(p.file)}</td><td>{_e(label(p.a))}</td><td>{_e(label(p.b))}</td>"
                       f'<td class="num">{p.score:.2f}</td><td class="num">{p.shared}</td></tr>\n'
                       for p in found.pairs)
        parts.append("<table><tr><th>File</th><th>Student</th><th>Student</th><th>Score</th>"
                     f"<th>Shared sequences</th></tr>\n{rows}</table>\n")
        for p in found.pairs:
            parts.append(
                f"<h3>{_e(p.file)}: {_e(label(p.a))} and {_e(label(p.b))} ({p.score:.2f})</h3>\n"
                f"<table><tr><th>{_e(p.a)}/{_e(p.file)}</th><th>{_e(p.b)}/{_e(p.file)}</th></tr>\n"
                f"<tr><td><pre>{_shown_lines(submissions / p.a / p.file, p.lines_a)}</pre></td>"
                f"<td><pre>{_shown_lines(submissions / p.b / p.file, p.lines_b)}</pre></td></tr></table>\n")
    else:
        parts.append("<p>No pair stands out.</p>\n")
    stats = "".join(f"<tr><td>{_e(name)}</td><td class=\"num\">{len(s.written)}</td>"
                    f'<td class="num">{len(s.scores)}</td><td class="num">{s.median:.2f}</td>'
                    f'<td class="num">{max(s.scores.values(), default=0.0):.2f}</td></tr>\n'
                    for name, s in found.files.items() if s.written)
    if stats:
        parts.append("<p>Per file: the written submissions compared, the pairs, their median score and the "
                     "highest.</p>\n<table><tr><th>File</th><th>Written</th><th>Pairs</th><th>Median</th>"
                     f"<th>Highest</th></tr>\n{stats}</table>\n")
    if found.notes:
        parts.append('<p class="note">Notes on the files compared:</p>\n<ul>'
                     + "".join(f"<li>{_e(note)}</li>" for note in found.notes) + "</ul>\n")
    return "".join(parts)


def _leaks_section(students: list, reference_dir, found) -> str:
    names = {s.sid: s for s in students}
    label = lambda sid: _who(names[sid]) if sid in names else sid
    if reference_dir is None:
        return '<p class="note">Not checked: no reference solution was given.</p>'
    if isinstance(found, Path):
        return f'<p class="note">Not checked: {_e(found)} is not a folder.</p>'
    leaks = found.leaks
    intro = (f"<p>Files that reproduce the reference's solution code (the code between the solution markers of "
             f"the reference, less what the stub gives): at least {similarity.LEAK_CONTAINMENT:.0%} of its "
             f"{similarity.NGRAM}-token sequences, names of variables, comments and blank lines ignored; files "
             f"whose solution has fewer than {similarity.LEAK_MIN_GRAMS} sequences are not checked. The pairs "
             "above discount the reference, so students who hand it in nearly unchanged, alone or several, "
             "show here only. A prompt to look, not a verdict.</p>\n")
    if not leaks:
        return intro + "<p>No file reproduces the reference's solution.</p>"
    by_file: dict = {}
    for leak in leaks:
        by_file.setdefault(leak.file, []).append(leak)
    rows = "".join(f"<tr><td>{_e(leak.file)}</td><td>{_e(label(leak.student))}</td>"
                   f'<td class="num">{leak.score:.2f}</td><td class="num">{leak.shared} / {leak.total}</td>'
                   f"<td>{len(by_file[leak.file])}</td></tr>\n" for leak in leaks)
    return intro + ("<table><tr><th>File</th><th>Student</th><th>Share of the solution</th><th>Sequences</th>"
                    f"<th>Students with this file's reference</th></tr>\n{rows}</table>\n")


def render(out_dir, stubs_dir, reference_dir=None) -> str:
    """The report's HTML."""
    out_dir = Path(out_dir)
    students, notes = load_students(out_dir)
    found = _compare(out_dir, Path(stubs_dir), reference_dir)
    when = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    unread = ("<ul>" + "".join(f"<li>{_e(n)}</li>" for n in notes) + "</ul>") if notes else ""
    reference = _e(reference_dir) if reference_dir is not None else "no reference given"
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>Class report: {_e(out_dir.name)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
        f"<h1>Class report</h1>\n{_headline(students)}\n{unread}\n"
        + _section("checks", "Full marks per check", _checks_table(students))
        + _section("mistakes", "Known mistakes per exercise", _mistakes_table(students))
        + _section("problems", "Submissions that did not run to the end", _problems_table(students))
        + _section("similar", "Similar submissions",
                   _similar_section(out_dir, students, Path(stubs_dir), reference_dir, found))
        + _section("leaked", "The reference's solution handed in",
                   _leaks_section(students, reference_dir, found))
        + f'<hr>\n<p id="footer" class="note">Written by <code>python -m autograder.classroom.report</code> '
        f"from {_e(out_dir.resolve())} (results/ and submissions/), stubs {_e(stubs_dir)}, {reference}, "
        f"on {_e(when)}.</p>\n</body>\n</html>\n")


def write_report(out_dir, stubs_dir, reference_dir=None) -> Path:
    """Write ``out_dir/report.html`` and return its path."""
    path = Path(out_dir) / "report.html"
    path.write_text(render(out_dir, stubs_dir, reference_dir), encoding="utf-8")
    return path


def write_for_this_tree(out_dir) -> Path:
    """:func:`write_report` with this tree's stubs (``exercises/``) and, where it has it, its
    reference (``solutions/``): what ``batch`` and ``merge`` write at the end."""
    from autograder.grade import reference_available
    from course.core.impl import REPO_ROOT

    return write_report(out_dir, REPO_ROOT / "exercises", REPO_ROOT / "solutions" if reference_available() else None)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m autograder.classroom.report", description=__doc__.splitlines()[0])
    p.add_argument("dir", type=Path, help="the --out folder of a batch run (results/, submissions/)")
    p.add_argument("--stubs", type=Path, default=Path("exercises"), help="the shipped stubs (default %(default)s)")
    p.add_argument("--reference", type=Path, default=None, help="the reference solutions, to discount")
    args = p.parse_args(argv)
    if not (args.dir / "results").is_dir():
        p.error(f"{args.dir / 'results'} is not a folder")
    print(write_report(args.dir, args.stubs, args.reference))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
