"""Written answers, graded: the questions of each assignment from its lessons, the answer sheet (which
holds nothing of the reference answers or the rubric), the rubric files and the marks CSV (their
mistakes named by file, key or line and field), the marks merged into the records' totals, the
gradebook and the Canvas file, and kept through a regrade. The class run (slow) grades two tiny uploads
with ``batch`` (the damping checks' public inputs), as ``tests/test_class_gradebook.py`` does."""

import csv
import json
import re
import subprocess
import sys
from datetime import datetime, timedelta, timezone
from types import SimpleNamespace

import pytest

from autograder.classroom import export, gradebook, marks, overrides, questions, rubric, written
from autograder.course_config import load
from autograder.late import LatePolicy, lateness
from autograder.release import assignment as handout
from autograder.release import stubs as release
from course.core.impl import REPO_ROOT

COURSE = load()
CH1 = COURSE.assignment("ch1")


def words(text: str, n: int = 8) -> set:
    tokens = re.findall(r"\w+", text.lower())
    return {tuple(tokens[i:i + n]) for i in range(len(tokens) - n + 1)}


# ---------------------------------------------------------------- the questions and the sheet


def test_each_assignment_asks_the_questions_of_the_lessons_that_check_its_exercises():
    asked = {name: [q.id for q in questions.of_assignment(a)] for name, a in COURSE.assignments.items()}
    assert asked["ch1"] == ["ch1-q1", "ch1-q2", "ch1-q3"]
    assert asked["ch3"] == ["ch3-q1", "ch3-q2", "ch3-q3", "ch3-q4"]  # not ch1's, whose code ch3 hands out solved
    for name, ids in asked.items():
        answers = (REPO_ROOT / "solutions" / "answers" / f"chapter{name[2:]}.md").read_text()
        assert len(ids) == len(re.findall(r"^## Question \d+:", answers, re.M)) >= 3, name
    both = SimpleNamespace(name="midterm", title="Midterm", exercises=("dogleg", "damping"))
    assert [q.id for q in questions.of_assignment(both)][::3] == ["ch1-q1", "ch3-q1", "ch3-q4"]
    first = questions.of_assignment(CH1)[0]
    assert first.text.startswith("From $(0, 0, 0)$, undamped Gauss-Newton") and first.text.endswith("fixes it.")
    assert first.lesson == "notebooks/chapter1_curve_fitting.ipynb"


def test_the_sheet_holds_the_questions_and_nothing_of_the_reference_answers_or_the_rubric():
    lessons = "\n".join(p.read_text() for p in questions.lessons())
    for name, assignment in COURSE.assignments.items():
        found = questions.of_assignment(assignment)
        rubrics = rubric.read(name, found)
        sheet = questions.sheet(assignment, found, {q: r.points for q, r in rubrics.items()})
        answers = (REPO_ROOT / "solutions" / "answers" / f"chapter{name[2:]}.md").read_text()
        # no run of 8 words of the answers that the lessons (which students have) do not hold as well
        assert not (words(sheet) & words(answers)) - words(lessons), name
        for bold in re.findall(r"\*\*([^*]{20,})\*\*", answers):
            assert bold not in sheet
        for r in rubrics.values():
            for item in r.items:
                assert item.text not in sheet
        for q in found:
            assert f"## {q.id} (4 points)" in sheet and q.text in sheet


def test_a_filled_sheet_reads_back_by_question_and_a_wrong_heading_names_its_line():
    found = questions.of_assignment(CH1)
    sheet = questions.sheet(CH1, found)
    filled = sheet.replace(f"\n{questions.PLACEHOLDER}\n", "\nThe step overshoots: $\\chi^2$ grows.\n", 1)
    assert questions.parse_sheet(filled, questions=found) == {
        "ch1-q1": "The step overshoots: $\\chi^2$ grows.", "ch1-q2": "", "ch1-q3": ""}
    with pytest.raises(questions.QuestionsError, match=r"answers.md: line \d+: heading '## ch1-q9' names no question"):
        questions.parse_sheet(filled + "\n## ch1-q9\n\nmore\n", questions=found)
    with pytest.raises(questions.QuestionsError, match="ch1-q2 answered twice"):
        questions.parse_sheet(filled + "\n## ch1-q2\n\nagain\n", questions=found)


def test_collect_gathers_the_sheets_one_document_per_question_and_names_the_missing(tmp_path, capsys):
    found = questions.of_assignment(CH1)
    blank = questions.sheet(CH1, found)
    for name, text in (("ada", blank.replace(f"\n{questions.PLACEHOLDER}\n", "\nAda: $\\chi^2$ explodes.\n", 1)),
                       ("bob", None), ("cy", blank.replace("## ch1-q2", "## question 2"))):
        (tmp_path / "uploads" / name / "sub").mkdir(parents=True)
        (tmp_path / "uploads" / name / "damping.py").write_text("x = 1\n")
        if text is not None:
            (tmp_path / "uploads" / name / "sub" / "Answers.md").write_text(text)
    assert written.main(["collect", "--assignment", "ch1", str(tmp_path / "uploads"), "--out",
                         str(tmp_path / "docs")]) == 0
    out, err = capsys.readouterr()
    assert "the sheets of 1 of 3 submissions" in out
    assert "bob: no answers.md" in err and "cy: " in err and "heading '## question 2' names no question" in err
    doc = (tmp_path / "docs" / "ch1-q1.md").read_text()
    assert doc.startswith("# ch1-q1: 4 points") and "- `trust-region` (2): a larger lambda" in doc
    assert "## ada\n\nAda: $\\chi^2$ explodes.\n" in doc and "## bob\n\n*(no answer)*" in doc
    assert sorted(p.name for p in (tmp_path / "docs").iterdir()) == ["ch1-q1.md", "ch1-q2.md", "ch1-q3.md"]


def test_the_export_command_writes_the_sheet_into_a_tree(tmp_path, capsys):
    assert written.main(["export", "--assignment", "ch2", "--out", str(tmp_path)]) == 0
    text = (tmp_path / "answers.md").read_text()
    assert text.startswith("# ch2: written answers") and text.count("\n## ch2-q") == 5
    assert written.main(["export", "--assignment", "ch9", "--out", str(tmp_path)]) == 2
    assert "ch9" in capsys.readouterr().err


def test_no_student_tree_holds_the_reference_answers_or_a_rubric(tmp_path):
    from autograder.isolation import reference_paths

    assert rubric.FOLDER.is_relative_to(REPO_ROOT / "solutions") and REPO_ROOT / "solutions" in reference_paths()
    assert not [name for name in release.render(REPO_ROOT / "solutions") if name.startswith(("rubrics", "answers"))]
    release.release(check=True, student_dir=tmp_path / "course")
    handout.write_student_tree(tmp_path / "ch1", COURSE, CH1, release.render(REPO_ROOT / "solutions"))
    for tree in (tmp_path / "course", tmp_path / "ch1"):
        files = [p.relative_to(tree).as_posix() for p in tree.rglob("*") if p.is_file()]
        assert "autograder/classroom/written.py" in files and "autograder/classroom/rubric.py" in files
        assert not [f for f in files if f.startswith("solutions/") or "answers/" in f or "rubrics/" in f]
        assert not [f for f in files if f.endswith(".md") and "Reference answers" in (tree / f).read_text()]


# ---------------------------------------------------------------- the rubric


def test_every_rubric_file_is_an_assignment_s_kept_from_students_and_valid():
    for path in sorted(rubric.FOLDER.glob("*")):
        assert path.suffix == ".toml" and path.stem in COURSE.assignments, path
        assert path.read_text().startswith(rubric.OMIT + "\n")
        found = questions.of_assignment(COURSE.assignment(path.stem))
        assert rubric.read(path.stem, found).keys() == {q.id for q in found}
    ch1 = rubric.read("ch1", questions.of_assignment(CH1))
    assert [i.id for i in ch1["ch1-q2"].items] == ["fixed-factors", "nu-doubles", "scaling"]


def test_the_default_rubric_round_trips_through_its_file(tmp_path):
    found = questions.of_assignment(COURSE.assignment("ch3"))
    rubrics = rubric.read("ch3", found, folder=tmp_path)  # no file: the default
    assert {r.points for r in rubrics.values()} == {4.0}
    (tmp_path / "ch3.toml").write_text(rubric.text_of("ch3", found, rubrics))
    assert rubric.read("ch3", found, folder=tmp_path) == rubrics
    assert "chapter3.md, question 2" in rubrics["ch3-q2"].items[0].text


@pytest.mark.parametrize("table, says", [
    ({"ch1-q4": {"points": 2}}, r"\[ch1-q4\]: no written question has this id \(did you mean ch1-q3"),
    ({"ch1-q1": {"points": 0}}, r"\[ch1-q1\].points: expected a number > 0, got 0"),
    ({"ch1-q1": {"item": []}}, r"\[ch1-q1\].item: unknown field \(did you mean items"),
    ({"ch1-q1": {"items": []}}, r"\[ch1-q1\].points: missing"),
    ({"ch1-q1": {"points": 3, "items": [{"id": "a", "points": 1, "text": "x"}]}},
     r"\[ch1-q1\].points: 3, but its items' points sum to 1"),
    ({"ch1-q1": {"points": 1, "items": [{"id": "a b", "points": 1, "text": "x"}]}}, r"\[ch1-q1\].items\[0\].id"),
    ({"ch1-q1": {"points": 2, "items": [{"id": "a", "points": 1, "text": "x"}, {"id": "a", "points": 1, "text": "y"}]}},
     r"\[ch1-q1\].items\[1\].id: 'a' is already an item"),
    ({"ch1-q1": {"points": 1, "items": [{"id": "a", "points": 1}]}}, r"\[ch1-q1\].items\[0\].text: missing"),
])
def test_a_rubric_mistake_names_the_file_the_key_and_the_field(table, says):
    with pytest.raises(rubric.RubricError, match="^ch1.toml: " + says):
        rubric.parse(table, questions.of_assignment(CH1), "ch1.toml")


# ---------------------------------------------------------------- the marks


def record(sub_id: str, scores, sid="", email="") -> dict:
    tests = [{"name": f"c{k}", "score": s, "max_score": 2.0, "output": "ok", "visibility": "visible",
              "extra_data": {"exercise": "damping", "hidden": False, "status": "ok"}} for k, s in enumerate(scores)]
    return {"score": sum(scores), "execution_time": 1.0, "output": "Total", "tests": tests,
            "extra_data": {"id": sub_id, "name": sub_id.title(), "sid": sid, "email": email, "status": "ok",
                           "assignment": "ch1"}}


def rubrics_of_ch1() -> dict:
    return rubric.read("ch1", questions.of_assignment(CH1))


@pytest.mark.parametrize("line, says", [
    ("carl,,ch1-q1,1,,", r"line 2: column id: 'carl' is no graded student"),
    ("ada,,ch1-q4,1,,", r"line 2: column question: 'ch1-q4' is no written question of this assignment \(did you"),
    ("ada,,ch1-q1,5,,", r"line 2: column points: 5 is above the maximum of ch1-q1, 4"),
    ("ada,,ch1-q1,-1,,", r"line 2: column points: expected a number >= 0, got '-1'"),
    ("ada,,ch1-q1,,linearized,", r"line 2: column items: 'linearized' is no rubric item of ch1-q1 \(did you mean "
                                 r"linearised"),
    ("ada,,ch1-q1,3,linearised,", r"line 2: column points: 3, but the items linearised are worth 2"),
    ("ada,,ch1-q1,1,,\nADA@x.edu,,ch1-q1,2,,", r"line 3: column question: ch1-q1 of ADA@x.edu is marked already on "
                                                r"line 2"),
    (",,ch1-q1,1,,", r"line 2: column id is empty"),
])
def test_a_marks_mistake_names_the_file_the_line_and_the_column(tmp_path, line, says):
    path = tmp_path / "written.csv"
    path.write_text("id,name,question,points,items,comment\n" + line + "\n")
    with pytest.raises(marks.MarksError, match="written.csv: " + says):
        marks.read(path, rubrics_of_ch1(), [record("ada", [2.0], email="ada@x.edu"), record("bob", [1.0])])


def test_a_marks_file_with_an_unknown_column_is_refused_at_line_1(tmp_path):
    path = tmp_path / "marks.csv"
    path.write_text("id,question,score\nada,ch1-q1,1\n")
    with pytest.raises(marks.MarksError, match=r"marks.csv: line 1: unknown column 'score'"):
        marks.read(path, rubrics_of_ch1(), [record("ada", [2.0])])


def test_merged_marks_count_in_the_total_after_the_penalty_and_the_overrides_and_in_canvas(tmp_path):
    due = datetime(2027, 2, 5, 23, 59, tzinfo=timezone.utc)
    when = due + timedelta(hours=2)
    late = lateness(when, due, LatePolicy(per_day=0.1))
    bob = gradebook.adjust(record("bob", [2.0, 2.0], sid="9002"), [overrides.Override("bob", "c1", 1.0, "by hand")],
                           late, due, when, "roster")
    folder = tmp_path / "ch1-grades"
    (folder / "results").mkdir(parents=True)
    for data in (record("ada", [2.0, 2.0], sid="9001"), bob):
        gradebook.save(folder / "results", data)
    (tmp_path / "marks.csv").write_text("id,name,question,points,items,comment\n"
                                        "9001,Ada,ch1-q1,,linearised;trust-region,\n9001,Ada,ch1-q2,4,,\n"
                                        "9001,Ada,ch1-q3,,rho-values;cap,\nbob,Bob,ch1-q1,2,,half of it\n"
                                        "bob,Bob,ch1-q2,,,\n")
    counts = written.merge(CH1, folder, tmp_path / "marks.csv")
    assert counts == {"records": 2, "changed": 2, "marked": 4, "unmarked": 2}
    assert (folder / "written.csv").read_text() == (tmp_path / "marks.csv").read_text()  # kept with the class
    with open(folder / "grades.csv", newline="") as file:
        table = {row["id"]: row for row in csv.DictReader(file)}
    assert (table["ada"]["total"], table["ada"]["max"], table["ada"]["written"]) == ("16", "16", "12")
    assert table["ada"]["written: ch1-q2"] == "4" and table["bob"]["written: ch1-q3"] == "0"
    assert table["bob"]["before_penalty"] == "5" and table["bob"]["total"] == "4.5"  # (2 + 1 + 2) * 0.9
    assert "by hand" in table["bob"]["overrides"]
    saved = gradebook.load(folder / "results" / "bob.json")
    outputs = {t["name"]: t["output"] for t in saved["tests"]}
    assert outputs["written: ch1-q1"] == "Written answer ch1-q1: 2 of 4 points.\nComment: half of it"
    assert "not marked yet" in outputs["written: ch1-q2"]
    assert [t["extra_data"]["marked"] for t in saved["tests"] if marks.is_written(t)] == [True, False, False]
    assert written.merge(CH1, folder)["changed"] == 0  # again, from DIR/written.csv: the same records
    canvas = tmp_path / "canvas.csv"
    assert export.main([str(folder), "--canvas", str(canvas)]) == 0
    lines = list(csv.reader(canvas.open(newline="")))
    assert lines[1][-1] == "16" and ["Ada", "", "9001", "", "", "16"] in lines
    assert ["Bob", "", "9002", "", "", "4.5"] in lines
    regraded = marks.keep(record("ada", [0.0, 2.0], sid="9001"), folder / "results" / "ada.json")
    assert gradebook.adjust(regraded)["score"] == 14.0  # the judge's new 2 and the 12 written points


def test_merge_refuses_a_class_of_another_assignment_or_without_records(tmp_path, capsys):
    folder = tmp_path / "out"
    (folder / "results").mkdir(parents=True)
    assert written.main(["merge", "--assignment", "ch1", "--class", str(folder)]) == 2
    assert "no record" in capsys.readouterr().err
    gradebook.save(folder / "results", {**record("ada", [1.0]), "extra_data": {**record("ada", [1.0])["extra_data"],
                                                                              "assignment": "ch2"}})
    assert written.main(["marks-template", "--assignment", "ch1", "--class", str(folder), "--out",
                         str(tmp_path / "m.csv")]) == 2
    assert "records of assignment ch2, not ch1" in capsys.readouterr().err


# ---------------------------------------------------------------- a class, end to end


def run(*args):
    proc = subprocess.run([sys.executable, "-m", *map(str, args)], cwd=REPO_ROOT, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc


@pytest.mark.slow
def test_a_class_with_written_marks_end_to_end(tmp_path):
    """batch grades two uploads, each with its filled answer sheet; the marks template is filled and
    merged; the Canvas file then holds the written points in the total; a regrade keeps them."""
    uploads, out = tmp_path / "uploads", tmp_path / "ch1-grades"
    run("autograder.classroom.written", "export", "--assignment", "ch1", "--out", tmp_path / "answers.md")
    blank = (tmp_path / "answers.md").read_text()
    for name in ("ada", "bob"):
        (uploads / name).mkdir(parents=True)
        (uploads / name / "damping.py").write_bytes((REPO_ROOT / "solutions" / "damping.py").read_bytes())
        (uploads / name / "answers.md").write_text(blank.replace(questions.PLACEHOLDER, f"{name} thinks so"))
    (tmp_path / "roster.csv").write_text("id,sid,email,name\nada,9001,ada@x.edu,Ada\nbob,9002,bob@x.edu,Bob\n")
    batch = ["autograder", "batch", uploads, "--out", out, "--only", "damping", "--set", "public", "--timeout", "3",
             "--jobs", "2", "--no-report", "--assignment", "ch1", "--roster", tmp_path / "roster.csv"]
    run(*batch)
    code = float(gradebook.load(out / "results" / "ada.json")["score"])
    sheet = questions.parse_sheet((uploads / "bob" / "answers.md").read_text(), questions=questions.of_assignment(CH1))
    assert set(sheet.values()) == {"bob thinks so"}
    run("autograder.classroom.written", "marks-template", "--assignment", "ch1", "--class", out,
        "--out", tmp_path / "marks.csv")
    with open(tmp_path / "marks.csv", newline="") as file:
        rows = list(csv.DictReader(file))
    assert [(r["id"], r["question"]) for r in rows][:4] == [("ada", "ch1-q1"), ("ada", "ch1-q2"), ("ada", "ch1-q3"),
                                                           ("bob", "ch1-q1")]
    for r in rows:
        r["points"] = "4" if r["id"] == "ada" else "1"
    with open(tmp_path / "marks.csv", "w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=marks.COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    done = run("autograder.classroom.written", "merge", "--assignment", "ch1", "--class", out,
               "--marks", tmp_path / "marks.csv")
    assert "merged 6 marks into 2 records" in done.stdout
    assert "Every submission ran to the end." in (out / "report.html").read_text()  # a mark is no problem
    run("autograder", "batch", *batch[2:], "--regrade", "ada")  # graded again: the marks stay
    run("autograder", "export", out, "--canvas", tmp_path / "canvas.csv", "--roster", tmp_path / "roster.csv")
    lines = list(csv.reader((tmp_path / "canvas.csv").open(newline="")))
    maximum = float(lines[1][5])
    scores = {row[0]: float(row[5]) for row in lines[2:]}
    assert scores == {"Ada": pytest.approx(code + 12), "Bob": pytest.approx(code + 3)}
    assert maximum == pytest.approx(code + 12)
    ada = json.loads((out / "results" / "ada.json").read_text())
    assert [t["score"] for t in ada["tests"] if marks.is_written(t)] == [4.0, 4.0, 4.0]
