"""The class's gradebook over a semester: submission times and the late penalty, the content hash
that regrades a changed submission, ``--regrade ID``, the instructor's overrides (kept through
every regrade), the Canvas and Moodle import files, and cells a spreadsheet would run as formulas.

The batch run (slow) grades a small Gradescope export (unpacked, as ``tests/test_classroom.py``
builds one) on the damping checks' public inputs; the rest works on hand-written records.
"""

import csv
import json
import subprocess
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from autograder.classroom import export, gradebook, intake, overrides, roster
from autograder.late import LatePolicy, lateness
from autograder.submission import content_hash, locate_submission
from course.core.impl import REPO_ROOT

ARGS = ["--only", "damping", "--set", "public", "--timeout", "3", "--jobs", "2", "--no-report"]
DUE = "2026-10-01T23:59:00-07:00"
LATE = ["--due", DUE, "--late-per-day", "0.1", "--assignment", "ch1"]
EVIL = "=HYPERLINK(\"http://x.example\",\"click\")"
T1_DIAG = "damping.GavinType1: damping_diagonal"

METADATA = f"""submission_1:
  :submitters:
  - :name: Ada On Time
    :sid: '9001'
    :email: ada@example.edu
  :created_at: 2026-10-01 10:00:00.000000000 -07:00
submission_2:
  :submitters:
  - :name: Bob Late
    :sid: '9002'
    :email: bob@example.edu
  :created_at: 2026-10-03 10:00:00.000000000 -07:00
submission_3:
  :submitters:
  - :name: '{EVIL.replace("'", "''")}'
    :sid: '9003'
  :created_at: 2026-09-30 10:00:00.000000000 -07:00
"""


def run(*args, check=True):
    proc = subprocess.run([sys.executable, "-m", "autograder", *map(str, args)], cwd=REPO_ROOT, capture_output=True,
                          text=True, timeout=600)
    if check:
        assert proc.returncode == 0, proc.stderr
    return proc


def rows(out) -> dict:
    with open(Path(out) / "grades.csv", newline="") as file:
        return {row["id"]: row for row in csv.DictReader(file)}


def stamps(out) -> dict:
    return {p.stem: p.stat().st_mtime_ns for p in (Path(out) / "results").glob("*.json")}


@pytest.mark.slow
def test_late_changed_regraded_and_overridden(tmp_path):
    export_dir = tmp_path / "assignment_1_export"
    reference = (REPO_ROOT / "solutions" / "damping.py").read_bytes()
    for number in (1, 2, 3):
        (export_dir / f"submission_{number}").mkdir(parents=True)
        (export_dir / f"submission_{number}" / "damping.py").write_bytes(reference)
    (export_dir / "submission_metadata.yml").write_text(METADATA)
    out = tmp_path / "out"
    out.mkdir()
    (out / "overrides.csv").write_text(f"id,check,points,reason\nada@example.edu,{T1_DIAG},0.5,partly copied\n")

    run("batch", export_dir, "--out", out, *ARGS, *LATE)
    first = rows(out)
    maximum = float(first["2"]["max"])
    # the late one: 1.42 days late, 2 started days at 10%: 80% kept, the penalty in its own column
    assert float(first["2"]["before_penalty"]) == pytest.approx(maximum)
    assert float(first["2"]["total"]) == pytest.approx(0.8 * maximum)
    assert float(first["2"]["penalty"]) == pytest.approx(0.2 * maximum)
    assert first["2"]["submitted"] == "2026-10-03T10:00:00-07:00" and float(first["2"]["days_late"]) > 1
    assert float(first["3"]["total"]) == pytest.approx(maximum) and float(first["3"]["penalty"]) == 0
    # the override: 0.5 instead of 2, in the table and in the student's feedback
    assert float(first["1"][T1_DIAG]) == 0.5 and float(first["1"]["total"]) == pytest.approx(maximum - 1.5)
    assert "partly copied" in first["1"]["overrides"] and first["1"]["assignment"] == "ch1"
    record = gradebook.load(out / "results" / "1.json")
    test = next(t for t in record["tests"] if t["name"] == T1_DIAG)
    assert test["output"].startswith("Override by the instructor: 0.5 points instead of 2: partly copied")
    late = gradebook.load(out / "results" / "2.json")
    assert late["output"].startswith("Late: submitted 2026-10-03T10:00:00-07:00")
    assert late["extra_data"]["late"]["penalty"] == pytest.approx(0.2 * maximum)
    assert (out / "results" / "2.txt").read_text().startswith("Late: submitted")
    assert "Total after the overrides and the penalty" in (out / "results" / "1.txt").read_text()
    # a formula-like name from the upload is text in grades.csv
    assert first["3"]["name"] == "'" + EVIL

    # submission 3 changes (the stub now): graded again without --regrade, the others are not
    before = stamps(out)
    (export_dir / "submission_3" / "damping.py").write_bytes((REPO_ROOT / "exercises" / "damping.py").read_bytes())
    proc = run("batch", export_dir, "--out", out, *ARGS, *LATE)
    assert "1 submission changed since graded, graded again: 3" in proc.stdout
    after = stamps(out)
    assert after["3"] != before["3"] and after["1"] == before["1"] and after["2"] == before["2"]
    second = rows(out)
    assert float(second["3"]["total"]) == 0 and float(second["1"]["total"]) == float(first["1"]["total"])

    # --regrade one student: only them; --regrade everyone: the override survives
    run("batch", export_dir, "--out", out, *ARGS, *LATE, "--regrade", "bob@example.edu")
    third = stamps(out)
    assert third["2"] != after["2"] and third["1"] == after["1"]
    run("batch", export_dir, "--out", out, *ARGS, *LATE, "--regrade")
    fourth = rows(out)
    assert stamps(out)["1"] != third["1"]
    assert float(fourth["1"][T1_DIAG]) == 0.5 and float(fourth["1"]["total"]) == float(first["1"]["total"])
    assert float(fourth["2"]["total"]) == pytest.approx(0.8 * maximum)
    assert (out / "results" / "1.txt").read_text().count("Override by the instructor") == 1
    assert run("batch", export_dir, "--out", out, *ARGS, "--regrade", "nobody", check=False).returncode == 2

    # the Canvas file: Canvas' columns, the points possible, the scores after the penalty
    canvas = tmp_path / "canvas.csv"
    run("export", out, "--canvas", canvas)
    table = list(csv.reader(canvas.open(newline="")))
    assert table[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "ch1"]
    assert table[1][0] == "Points Possible" and float(table[1][5]) == pytest.approx(maximum)
    by_sid = {row[2]: row for row in table[2:]}
    assert float(by_sid["9002"][5]) == pytest.approx(0.8 * maximum)
    assert by_sid["9003"][0] == "'" + EVIL


def test_a_formula_like_cell_is_written_as_text():
    for text in ("=1+1", "+41", "-2+3", "@SUM(A1)", "\tx", "\rx"):
        assert gradebook.cell(text) == "'" + text
    assert gradebook.cell("Ada") == "Ada" and gradebook.cell("") == "" and gradebook.cell(None) == ""
    table = gradebook.table([record("=cmd|' /C calc'!A0", "-folder", [2.0, 1.0])])
    header, row = list(csv.reader(table.splitlines()))
    assert row[0] == "'-folder" and row[1] == "'=cmd|' /C calc'!A0"
    assert row[header.index("total")] == "3"  # numbers stay numbers


def record(name: str, sub_id: str, scores, sid="", email="", assignment="", status="ok") -> dict:
    tests = [{"name": f"c{k}", "score": s, "max_score": 2.0, "output": "ok", "visibility": "visible",
              "extra_data": {"exercise": "damping", "hidden": False, "status": "ok"}} for k, s in enumerate(scores)]
    return {"score": sum(scores), "execution_time": 1.0, "output": "Total", "tests": tests,
            "extra_data": {"id": sub_id, "name": name, "sid": sid, "email": email, "status": status,
                           "assignment": assignment}}


def test_adjust_is_idempotent_and_keeps_the_judges_scores():
    data = record("Ada", "1", [2.0, 2.0])
    due = datetime(2026, 10, 1, 23, 59, tzinfo=timezone.utc)
    when = due + timedelta(hours=30)
    late = lateness(when, due, LatePolicy(per_day=0.25))
    fix = [overrides.Override("1", "c0", 1.0, "half the derivation")]
    once = gradebook.adjust(data, fix, late, due, when, "roster")
    assert once["score"] == pytest.approx(1.5) and once["extra_data"]["score_before_penalty"] == 3.0
    assert once["extra_data"]["graded_score"] == 4.0 and once["extra_data"]["late"]["penalty"] == pytest.approx(1.5)
    assert gradebook.adjust(once, fix, late, due, when, "roster") == once
    undone = gradebook.adjust(once)  # no override, no policy: the judge's record again
    assert undone["score"] == 4.0 and [t["score"] for t in undone["tests"]] == [2.0, 2.0]
    assert undone["output"] == "Total" and "override" not in undone["tests"][0]["extra_data"]


def test_times_rosters_and_overrides_are_read_or_refused_with_the_line(tmp_path):
    assert intake.parse_time("2026-11-20 10:00:00.000000000 -08:00") == \
        datetime(2026, 11, 20, 18, 0, tzinfo=timezone.utc)
    assert intake.parse_time("2026-10-01T23:59").tzinfo == timezone.utc
    with pytest.raises(ValueError, match="not a time"):
        intake.parse_time("next tuesday")
    path = tmp_path / "roster.csv"
    path.write_text("ID,SID,Email,Name,Submitted,Due\nada-folder,9001,ada@x.edu,Ada L,2026-10-02T01:00:00Z,\n"
                    "bob,9002,,Bob,,2026-10-05T00:00:00Z\n")
    known = roster.read(path)
    assert known.find("ADA@x.edu").name == "Ada L" and known.find("9002").due.day == 5
    assert known.find("200; 9002").sid == "9002" and known.find("nobody") is None
    path.write_text("id,submitted\nada,yesterday\n")
    with pytest.raises(roster.RosterError, match=r"roster.csv: line 2: column submitted"):
        roster.read(path)
    path.write_text("who,when\n")
    with pytest.raises(roster.RosterError, match="no column id, sid or email"):
        roster.read(path)
    bad = tmp_path / "overrides.csv"
    bad.write_text("id,check,points,reason\n1,c0,-1,no\n")
    with pytest.raises(overrides.OverridesError, match="line 2: column points"):
        overrides.read(bad)
    bad.write_text("id,check,points,reason\n1,c0,1,\n")
    with pytest.raises(overrides.OverridesError, match="line 2: column reason is empty"):
        overrides.read(bad)
    assert overrides.read(tmp_path / "absent.csv") == []


def test_a_folder_of_uploads_takes_the_newest_files_time_and_the_roster_wins(tmp_path):
    folder = tmp_path / "uploads" / "ada-folder"
    folder.mkdir(parents=True)
    (folder / "damping.py").write_text("x = 1\n")
    import os

    stamp = datetime(2026, 10, 2, 12, 0, tzinfo=timezone.utc).timestamp()
    os.utime(folder / "damping.py", (stamp, stamp))
    sub = intake.read(tmp_path / "uploads")[0]
    assert sub.submitted == datetime(2026, 10, 2, 12, 0, tzinfo=timezone.utc) and sub.submitted_from == "file time"
    (tmp_path / "roster.csv").write_text("id,sid,name,submitted\nada-folder,9001,Ada L,2026-10-01T08:00:00Z\n")
    known = roster.read(tmp_path / "roster.csv")
    mapped = roster.apply(sub, known.find(sub.id, sub.path.name))
    assert (mapped.name, mapped.sid, mapped.submitted_from) == ("Ada L", "9001", "roster")
    assert mapped.submitted.hour == 8


def test_the_content_hash_follows_the_exercise_files_only(tmp_path):
    modules = ["damping.py", "curve_model.py"]
    (tmp_path / "damping.py").write_text("a = 1\n")
    (tmp_path / "notes.txt").write_text("draft\n")
    first = content_hash(locate_submission(tmp_path, modules))
    (tmp_path / "notes.txt").write_text("other draft\n")
    assert content_hash(locate_submission(tmp_path, modules)) == first
    (tmp_path / "damping.py").write_text("a = 2\n")
    assert content_hash(locate_submission(tmp_path, modules)) != first


def write_dir(folder: Path, records) -> Path:
    (folder / "results").mkdir(parents=True)
    for data in records:
        (folder / "results" / f"{data['extra_data']['id']}.json").write_text(json.dumps(data))
    return folder


def test_export_joins_assignments_maps_the_roster_and_splits_groups(tmp_path, capsys):
    ch1 = write_dir(tmp_path / "ch1-out", [record("Ada", "11", [2.0, 2.0], sid="9001", email="ada@x.edu",
                                                  assignment="ch1"),
                                           record("Pair One; Pair Two", "12", [1.0, 0.0], sid="200; 201",
                                                  assignment="ch1")])
    ch2 = write_dir(tmp_path / "ch2", [record("ada-folder", "ada-folder", [2.0]),
                                       record("@evil", "evil", [0.0])])
    (tmp_path / "roster.csv").write_text("id,sid,email,name,login,canvas_id,section\n"
                                         "ada-folder,9001,ada@x.edu,Ada Lovelace,alove,501,S1\n")
    canvas, moodle = tmp_path / "canvas.csv", tmp_path / "moodle.csv"
    assert export.main([str(ch1), str(ch2), "--roster", str(tmp_path / "roster.csv"), "--canvas", str(canvas),
                        "--moodle", str(moodle), "--column", "ch2=Homework 2 (4521)"]) == 0
    table = list(csv.reader(canvas.open(newline="")))
    assert table[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "ch1", "Homework 2 (4521)"]
    assert table[1] == ["Points Possible", "", "", "", "", "4", "2"]
    people = {row[0]: row for row in table[2:]}
    assert people["Ada Lovelace"] == ["Ada Lovelace", "501", "9001", "alove", "S1", "4", "2"]  # both assignments
    assert people["Pair One"][2:] == ["200", "", "", "1", ""] and people["Pair Two"][2] == "201"
    assert people["'@evil"][5:] == ["", "0"]
    err = capsys.readouterr().err  # a row the platform cannot match to a user is named
    assert "@evil has no ID, SIS User ID or SIS Login ID" in err and "cannot match" in err
    mtable = list(csv.reader(moodle.open(newline="")))
    assert mtable[0] == ["Full name", "ID number", "Email address", "ch1", "Homework 2 (4521)"]
    assert ["Ada Lovelace", "9001", "ada@x.edu", "4", "2"] in mtable


@pytest.mark.slow
def test_a_folder_of_uploads_with_a_roster_times_and_an_extension(tmp_path):
    """Folder names only: the roster gives the sid and e-mail, one student's time (the files' time
    is the other's) and an extension; the Moodle file then has the ids."""
    import os

    uploads = tmp_path / "uploads"
    reference = (REPO_ROOT / "solutions" / "damping.py").read_bytes()
    for name in ("ada", "bob"):
        (uploads / name).mkdir(parents=True)
        (uploads / name / "damping.py").write_bytes(reference)
    late = datetime(2026, 10, 3, 12, 0, tzinfo=timezone.utc).timestamp()  # 2.5 days after the due date
    os.utime(uploads / "bob" / "damping.py", (late, late))
    (tmp_path / "roster.csv").write_text("id,sid,email,name,submitted,due\n"
                                         "ada,9001,ada@x.edu,Ada Lovelace,2026-10-04T00:00:00Z,2026-10-05T00:00:00Z\n"
                                         "bob,9002,bob@x.edu,Bob,,\n")
    out = tmp_path / "out"
    proc = run("batch", uploads, "--out", out, *ARGS, "--due", "2026-10-01T00:00:00Z", "--late-per-day", "0.2",
               "--cutoff-days", "7", "--roster", tmp_path / "roster.csv")
    assert "modification times" in proc.stderr
    table = rows(out)
    maximum = float(table["ada"]["max"])
    assert table["ada"]["sid"] == "9001" and table["ada"]["name"] == "Ada Lovelace"
    assert float(table["ada"]["total"]) == pytest.approx(maximum)  # the extension
    assert table["bob"]["submitted"].startswith("2026-10-03T12:00:00")
    assert float(table["bob"]["total"]) == pytest.approx(0.4 * maximum)  # 3 started days at 20%
    assert gradebook.load(out / "results" / "bob.json")["extra_data"]["submitted_from"] == "file time"
    moodle = tmp_path / "moodle.csv"
    run("export", out, "--moodle", moodle)
    lines = list(csv.reader(moodle.open(newline="")))
    assert lines[0] == ["Full name", "ID number", "Email address", "out"]
    assert ["Bob", "9002", "bob@x.edu", gradebook.number(0.4 * maximum)] in lines


@pytest.mark.slow
def test_an_assignment_of_the_configuration_gives_its_points_and_its_late_policy(tmp_path):
    """``--assignment ch1`` without ``--due``: ch1's checks with ch1's points, and ch1's due date and
    policy from the course configuration (a submission after it pays the configured penalty)."""
    import os

    from autograder import course_config

    ch1 = course_config.load().assignment("ch1")
    uploads = tmp_path / "uploads"
    (uploads / "ada").mkdir(parents=True)
    (uploads / "ada" / "damping.py").write_bytes((REPO_ROOT / "solutions" / "damping.py").read_bytes())
    when = (ch1.due + timedelta(days=1, hours=1)).timestamp()
    os.utime(uploads / "ada" / "damping.py", (when, when))
    out = tmp_path / "out"
    run("batch", uploads, "--out", out, "--only", "damping", "--set", "public", "--timeout", "3", "--jobs", "2",
        "--no-report", "--assignment", "ch1")
    row = rows(out)["ada"]
    maximum = sum(c.points for c in ch1.checks() if c.exercise.startswith("damping.") and not ch1.is_extra(c))
    assert float(row["max"]) == pytest.approx(maximum) and row["assignment"] == "ch1"
    kept = ch1.lateness(datetime.fromtimestamp(when, timezone.utc)).fraction
    assert kept < 1.0 and float(row["total"]) == pytest.approx(kept * maximum)
    proc = run("batch", uploads, "--out", tmp_path / "x", "--assignment", "ch9", check=False)
    assert proc.returncode == 2 and "ch9" in proc.stderr
