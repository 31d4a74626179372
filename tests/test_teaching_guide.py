"""Every command of the teaching guide (docs/teaching.md) runs, in order, from a working folder of
its own, with the class it grades made here: two students' uploads of chapter 1 (one complete, one
with a wrong residual sign, submitted after the due date), a roster of three (one sent nothing),
Canvas' gradebook export and an override."""

import csv
import os
import re
import shlex
import subprocess
import sys
from datetime import timedelta
from pathlib import Path

import pytest

from course.core.impl import REPO_ROOT

GUIDE = REPO_ROOT / "docs" / "teaching.md"


def commands() -> list:
    """The guide's commands: each line of its ```bash blocks."""
    blocks = re.findall(r"```bash\n(.*?)```", GUIDE.read_text(), re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


def test_the_guide_shows_commands_and_only_the_course_s():
    lines = commands()
    assert len(lines) >= 8
    assert all(shlex.split(line)[:2] == ["python", "-m"] for line in lines)


def make_class(work: Path) -> None:
    from autograder import course_config
    from autograder.classroom import questions

    ch1 = course_config.load().assignment("ch1")
    sheet = questions.sheet(ch1, questions.of_assignment(ch1))
    for student in ("ada", "bob"):
        (work / "semester" / "uploads" / student).mkdir(parents=True)
        for name in ("curve_model", "gauss_newton", "damping"):
            text = (REPO_ROOT / "solutions" / f"{name}.py").read_text()
            if student == "bob" and name == "curve_model":
                text = text.replace("r = y_hat - y", "r = y - y_hat")
            (work / "semester" / "uploads" / student / f"{name}.py").write_text(text)
        (work / "semester" / "uploads" / student / "answers.md").write_text(sheet.replace("*(your answer)*", student))
    late = (ch1.due + timedelta(hours=5)).timestamp()
    for path in (work / "semester" / "uploads" / "bob").iterdir():
        os.utime(path, (late, late))
    (work / "semester" / "roster.csv").write_text("id,sid,email,name\nada,9001,ada@example.edu,Ada\n"
                                                  "bob,9002,bob@example.edu,Bob\ncy,9003,cy@example.edu,Cy\n")
    (work / "semester" / "canvas-export.csv").write_text(  # as Canvas exports its gradebook
        "Student,ID,SIS User ID,SIS Login ID,Section,Homework 1 (4521),Current Score\n"
        "Points Possible,,,,,10,(read only)\n\"Lovelace, Ada\",501,9001,ada,S1,,\n"
        "\"Bob, Bob\",502,9002,bob,S1,,\n\"Cy, Cy\",503,9003,cy,S2,,\n")
    (work / "semester" / "overrides.csv").write_text(
        "id,check,points,reason\nbob,curve_model.residuals_and_jacobian: r values,2,the sign slip was the only one\n")
    (work / "semester" / "ch1-marks.csv").write_text(  # the written answers' marks: Ada's in full
        "id,name,question,points,items,comment\nada,Ada,ch1-q1,,linearised;trust-region,\nada,Ada,ch1-q2,4,,\n"
        "ada,Ada,ch1-q3,,rho-values;cap,\nbob,Bob,ch1-q1,1,,\"the step, not the reason\"\n")


@pytest.mark.slow
def test_every_command_of_the_guide_runs(tmp_path):
    make_class(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    for line in commands():
        argv = [sys.executable] + shlex.split(line)[1:]
        done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{line}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
    semester = tmp_path / "semester"
    assert (semester / "ch1-tree" / "README.md").is_file() and (semester / "ch1.zip").is_file()
    with open(semester / "ch1-grades" / "grades.csv", newline="") as file:
        table = {row["id"]: row for row in csv.DictReader(file)}
    assert float(table["ada"]["total"]) == pytest.approx(float(table["ada"]["max"]))
    assert float(table["bob"]["total"]) < float(table["ada"]["total"]) and float(table["bob"]["penalty"]) > 0
    assert "sign slip" in table["bob"]["overrides"]  # kept by the graded folder through the plain run after
    assert (semester / "ch1-grades" / "overrides.csv").read_text().count("sign slip") == 1
    assert table["cy"]["status"] == "no submission" and float(table["cy"]["total"]) == 0
    assert (table["ada"]["written"], table["bob"]["written"]) == ("12", "1")
    assert "## ch1-q1 (4 points)" in (semester / "ch1-tree" / "answers.md").read_text()
    assert "## bob\n\nbob\n" in (semester / "ch1-answers" / "ch1-q3.md").read_text()
    with open(semester / "canvas.csv", newline="") as file:
        canvas = list(csv.reader(file))
    assert canvas[0] == ["Student", "ID", "SIS User ID", "SIS Login ID", "Section", "Homework 1 (4521)"]
    assert ["Cy, Cy", "503", "9003", "cy", "S2", "0"] in canvas and len(canvas) == 2 + 3
    feedback = (semester / "ch1-grades" / "feedback" / "bob" / "feedback.txt").read_text()
    assert "Override by the instructor" in feedback and feedback.splitlines()[1].startswith("Total: ")
    assert (semester / "moodle.csv").read_text().startswith("Full name,ID number,Email address")
