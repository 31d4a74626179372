# RELEASE: omit
"""Reference answers to the notebooks' written questions (instructors only).

``chapter2.md`` answers the five questions of ``notebooks/chapter2_pose_graphs.ipynb``.
Every file here starts with ``# RELEASE: omit``, so ``python -m course release`` keeps
it out of ``exercises/`` (and the student tree has no ``solutions/`` at all).
"""

from pathlib import Path

HERE = Path(__file__).resolve().parent


def answers(chapter: int) -> str:
    """The reference answers of ``chapter`` as markdown text."""
    return (HERE / f"chapter{chapter}.md").read_text()
