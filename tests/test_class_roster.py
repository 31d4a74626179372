"""Every roster student in the gradebook, the platforms' own files as rosters, the assignment columns
mapped to the platform's, and the feedback returned to each student.

The batch run (slow) grades a class of five from Canvas' gradebook export, one of whom sent
nothing, on the damping checks' public inputs; the rest works on hand-written records.
"""

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from autograder.classroom import export, gradebook, overrides, roster, student_feedback
from course.core.impl import REPO_ROOT

ARGS = ["--only", "damping", "--set", "public", "--timeout", "3", "--jobs", "2", "--no-report"]

#: Canvas' gradebook export as downloaded: the points row, the test student, a computed column
CANVAS_EXPORT = """Student,ID,SIS User ID,SIS Login ID,Section,hw1 (4521),Quiz 1 (4522),Current Score,Final Score
Points Possible,,,,,10,5,(read only),(read only)
"Lovelace, Ada",501,9001,ada,S1,,,,
"Babbage, Charles",502,9002,charles,S1,,,,
"Noether, Emmy",503,9003,emmy,S2,,,,
"Hopper, Grace",504,9004,grace,S2,,,,
"Turing, Alan",505,9005,alan,S2,,,,
"Student, Test",506,,,S1,,,,
"""

GRADESCOPE_GRADES = """First Name,Last Name,SID,Email,Sections,Total Score,Max Points,Status,Submission ID
Ada,Lovelace,9001,ada@x.edu,S1,10.0,10.0,Graded,11
Alan,Turing,9005,alan@x.edu,S2,,10.0,Missing,
"""


def run(*args, check=True):
    proc = subprocess.run([sys.executable, "-m", "autograder", *map(str, args)], cwd=REPO_ROOT, capture_output=True,
                          text=True, timeout=600)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


@pytest.mark.slow
def test_a_roster_of_five_with_one_missing_submission_gives_five_rows(tmp_path):
    uploads = tmp_path / "uploads"
    reference = (REPO_ROOT / "solutions" / "damping.py").read_text()
    for login in ("ada", "charles", "emmy", "grace"):  # alan sent nothing
        (uploads / login).mkdir(parents=True)
        slip = ("return lam * np.asarray(diag_H)\n", "return lam * np.ones_like(diag_H)\n")
        text = reference if login != "emmy" else reference.replace(*slip)
        (uploads / login / "damping.py").write_text(text)
    (tmp_path / "canvas-export.csv").write_text(CANVAS_EXPORT)
    out = tmp_path / "hw1"
    proc = run("batch", uploads, "--out", out, *ARGS, "--roster", tmp_path / "canvas-export.csv")
    assert "1 roster student without a submission (0 points): 9005" in proc.stdout

    with open(out / "grades.csv", newline="") as file:
        table = {row["sid"]: row for row in csv.DictReader(file)}
    assert len(table) == 5
    assert table["9005"]["status"] == "no submission" and float(table["9005"]["total"]) == 0
    assert table["9005"]["name"] == "Turing, Alan" and float(table["9005"]["max"]) == float(table["9001"]["max"])
    maximum = float(table["9001"]["max"])
    assert float(table["9001"]["total"]) == pytest.approx(maximum) and table["9001"]["name"] == "Lovelace, Ada"
    assert float(table["9003"]["total"]) < maximum

    # Canvas: no --roster here: the ids, logins and sections come from the records; hw1 maps to Canvas' column
    canvas = tmp_path / "canvas.csv"
    run("export", out, "--canvas", canvas)
    rows = list(csv.reader(canvas.open(newline="")))
    assert rows[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "hw1"]
    by_id = {row[1]: row for row in rows[2:]}
    assert len(by_id) == 5
    assert by_id["505"] == ["Turing, Alan", "505", "9005", "alan", "S2", "0"]
    assert by_id["501"][:5] == ["Lovelace, Ada", "501", "9001", "ada", "S1"]
    assert float(by_id["501"][5]) == pytest.approx(maximum)
    # with Canvas' export as the roster, the column is Canvas' own assignment
    proc = run("export", out, "--canvas", canvas, "--roster", tmp_path / "canvas-export.csv")
    assert next(csv.reader(canvas.open(newline="")))[5] == "hw1 (4521)" and proc.stderr == ""

    # the feedback folder of each student, the absent one's too
    folders = sorted(p.name for p in (out / "feedback").iterdir() if p.is_dir())
    assert folders == ["9005", "ada", "charles", "emmy", "grace"]
    emmy = (out / "feedback" / "emmy" / "feedback.txt").read_text()
    record = gradebook.load(out / "results" / "emmy.json")
    assert f"Total: {gradebook.number(record['score'])} / {gradebook.number(maximum)}" in emmy
    failed = [t for t in record["tests"] if t["score"] < t["max_score"]]
    assert failed and all(t["name"] in emmy and t["output"].splitlines()[0] in emmy for t in failed)
    returned = json.loads((out / "feedback" / "emmy" / "results.json").read_text())
    assert returned["score"] == record["score"] and "extra_data" not in returned
    assert [t["name"] for t in returned["tests"]] == [t["name"] for t in record["tests"]]
    assert "No submission." in (out / "feedback" / "9005" / "feedback.txt").read_text()
    with open(out / "feedback" / "index.csv", newline="") as file:
        index = {row["folder"]: row for row in csv.DictReader(file)}
    assert index["9005"]["sid"] == "9005" and index["9005"]["total"] == "0"

    # Alan submits after all: his no-submission record and its feedback folder go (the roster kept with the class)
    (uploads / "alan").mkdir()
    (uploads / "alan" / "damping.py").write_text(reference)
    assert (out / "roster.csv").read_text() == CANVAS_EXPORT
    run("batch", uploads, "--out", out, *ARGS)
    with open(out / "grades.csv", newline="") as file:
        again = {row["sid"]: row for row in csv.DictReader(file)}
    assert len(again) == 5 and again["9005"]["id"] == "alan" and float(again["9005"]["total"]) == maximum
    assert not (out / "results" / "9005.json").exists() and not (out / "feedback" / "9005").exists()
    assert gradebook.load(out / "results" / "alan.json")["extra_data"]["roster"][0]["canvas_id"] == "505"


def test_canvas_and_gradescope_exports_are_rosters(tmp_path):
    (tmp_path / "canvas.csv").write_text(CANVAS_EXPORT)
    known = roster.read(tmp_path / "canvas.csv")
    assert len(known.students) == 5  # no points row, no test student
    ada = known.find("ada")
    assert (ada.name, ada.canvas_id, ada.sid, ada.login, ada.section) == ("Lovelace, Ada", "501", "9001", "ada", "S1")
    assert known.assignments == ["hw1 (4521)", "Quiz 1 (4522)"]
    (tmp_path / "gradescope.csv").write_text(GRADESCOPE_GRADES)
    known = roster.read(tmp_path / "gradescope.csv")
    assert [(s.name, s.sid, s.email, s.section) for s in known.students] == [
        ("Ada Lovelace", "9001", "ada@x.edu", "S1"), ("Alan Turing", "9005", "alan@x.edu", "S2")]
    (tmp_path / "empty.csv").write_text("Student,ID,SIS User ID,SIS Login ID,Section\nPoints Possible,,,,\n")
    with pytest.raises(roster.RosterError, match="empty.csv: Canvas' gradebook export with no student"):
        roster.read(tmp_path / "empty.csv")


def record(sub_id: str, scores, name="", sid="", email="", assignment="hw1", hidden_visibility="after_published"):
    tests = [{"name": f"c{k}", "score": s, "max_score": 2.0, "output": f"check {k}: {'ok' if s == 2 else 'wrong'}",
              "visibility": "visible", "extra_data": {"exercise": "damping", "hidden": False, "status": "ok"}}
             for k, s in enumerate(scores)]
    tests.append({"name": "c0 (hidden)", "score": 2.0, "max_score": 2.0, "output": "fresh inputs: ok",
                  "visibility": hidden_visibility, "extra_data": {"exercise": "damping", "hidden": True}})
    return {"score": sum(scores) + 2.0, "execution_time": 1.0, "output": "Graded damping.py", "tests": tests,
            "extra_data": {"id": sub_id, "name": name, "sid": sid, "email": email, "status": "ok",
                           "assignment": assignment}}


def write_dir(folder: Path, records) -> Path:
    (folder / "results").mkdir(parents=True)
    for data in records:
        gradebook.save(folder / "results", data)
    return folder


def test_export_gives_every_roster_student_a_row_and_an_unknown_column_is_an_error(tmp_path, capsys):
    hw1 = write_dir(tmp_path / "hw1", [record("11", [2.0, 1.0], "Ada", "9001", "ada@x.edu")])
    (tmp_path / "roster.csv").write_text("sid,email,name,section\n9001,ada@x.edu,Ada L,S1\n9005,alan@x.edu,Alan,S2\n")
    canvas, moodle = tmp_path / "canvas.csv", tmp_path / "moodle.csv"
    assert export.main([str(hw1), "--roster", str(tmp_path / "roster.csv"), "--canvas", str(canvas),
                        "--moodle", str(moodle), "--column", "hw1=Homework 1 (4521)"]) == 0
    rows = list(csv.reader(canvas.open(newline="")))
    assert rows[0][5] == "Homework 1 (4521)" and rows[1][5] == "6"
    assert ["Alan", "", "9005", "", "S2", "0"] in rows and ["Ada L", "", "9001", "", "S1", "5"] in rows
    assert ["Alan", "9005", "alan@x.edu", "0"] in list(csv.reader(moodle.open(newline="")))
    capsys.readouterr()
    with pytest.raises(SystemExit) as stop:
        export.main([str(hw1), "--canvas", str(canvas), "--column", "ch3=Homework 3 (4523)"])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert "--column ch3=Homework 3 (4523): no assignment 'ch3'" in err and "are: hw1" in err
    # Canvas' export as the roster: a column Canvas does not have is named
    (tmp_path / "canvas-export.csv").write_text(CANVAS_EXPORT)
    assert export.main([str(hw1), "--canvas", str(canvas), "--roster", str(tmp_path / "canvas-export.csv"),
                        "--column", "hw1=Homework 1"]) == 0
    assert "'Homework 1' (assignment hw1) is not an assignment of" in capsys.readouterr().err


def test_the_feedback_is_gradescope_s_text_without_what_students_never_see(tmp_path):
    data = gradebook.adjust(record("11", [2.0, 1.0], "Ada", hidden_visibility="hidden"),
                            [overrides.Override("11", "c1", 1.5, "a slip in the notation")])
    out = write_dir(tmp_path / "hw1", [data, record("12", [0.0, 0.0], "Bob")])
    student_feedback.write(out)
    text = (out / "feedback" / "11" / "feedback.txt").read_text()
    assert text.startswith("hw1: Ada\nTotal: 5.5 / 6\n")
    assert "c1: 1.5 / 2\n    Override by the instructor: 1.5 points instead of 1: a slip in the notation" in text
    assert "c0: 2 / 2\n    check 0: ok" in text and "(hidden)" not in text and "Graded damping.py" in text
    shown = json.loads((out / "feedback" / "11" / "results.json").read_text())
    assert [t["name"] for t in shown["tests"]] == ["c0", "c1"] and shown["score"] == 5.5
    bob = (out / "feedback" / "12" / "feedback.txt").read_text()
    assert "c0 (hidden): 2 / 2\n    fresh inputs: ok" in bob and "Total: 2 / 6" in bob
