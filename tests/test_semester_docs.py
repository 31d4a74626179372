"""The README and the teaching guide name every assignment the configuration ships (and the README
every exercise of each), so that a new chapter's assignment cannot go unmentioned."""

import re

from autograder.course_config import load
from course.core.impl import REPO_ROOT


def test_the_readme_and_the_guide_name_every_assignment():
    course = load()
    readme = (REPO_ROOT / "README.md").read_text()
    guide = (REPO_ROOT / "docs" / "teaching.md").read_text()
    listing = re.search(r"It ships with one assignment per chapter: (.*?)every check in\s+exactly one", readme, re.S)
    assert listing, "the README's list of the shipped assignments"
    text = " ".join(listing.group(1).split())
    for name, assignment in course.assignments.items():
        assert f"`{name}` (" in text, name
        described = text.split(f"`{name}` (", 1)[1].split(")", 1)[0]
        assert all(exercise in described for exercise in assignment.exercises), (name, described)
        assert f"`{name}`" in guide, name
