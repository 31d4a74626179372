"""The README's table of the chapters and the teaching guide name every assignment the configuration
ships, with every exercise of each, and every chapter's lesson, so that a new chapter's assignment
cannot go unmentioned."""

import re

from autograder.course_config import load
from course.core.chapters import CHAPTERS
from course.core.impl import REPO_ROOT


def test_the_readme_s_table_names_every_chapter_s_lesson_and_assignment():
    course = load()
    readme = (REPO_ROOT / "README.md").read_text()
    rows = [line for line in readme.splitlines() if re.match(r"\| \d+b?\. ", line)]
    assert len(rows) == len(CHAPTERS), "a row of the README's table of the chapters per chapter"
    for chapter, row in zip(CHAPTERS, rows):
        number = chapter.name.removeprefix("ch")
        assert row.startswith(f"| {number}. "), (chapter.name, row)
        lessons = sorted(p.name for p in (REPO_ROOT / "notebooks").glob(f"chapter{number}_*.ipynb"))
        assert len(lessons) == 1 and f"(notebooks/{lessons[0]})" in row, (chapter.name, lessons, row)
        assignment = row.rsplit("|", 2)[-2]
        assert f"`{chapter.name}`:" in assignment, (chapter.name, row)
        for exercise in course.assignment(chapter.name).exercises:
            assert re.search(rf"[ *]{exercise}\b", assignment), (chapter.name, exercise, row)
    assert {chapter.name for chapter in CHAPTERS} == set(course.assignments)


def test_the_guide_names_every_assignment_and_its_exercises():
    course = load()
    guide = (REPO_ROOT / "docs" / "teaching.md").read_text()
    listing = re.search(r"It ships with one assignment per chapter: (.*?)every check in\s+exactly one", guide, re.S)
    assert listing, "the teaching guide's list of the shipped assignments"
    text = " ".join(listing.group(1).split())
    for name, assignment in course.assignments.items():
        assert f"`{name}` (" in text, name
        described = text.split(f"`{name}` (", 1)[1].split(")", 1)[0]
        assert all(exercise in described for exercise in assignment.exercises), (name, described)
        assert f"`{name}`" in guide.split("## 2.", 1)[0], name  # in the walk's first section too
