"""A page generated from the project's own sources (``docs/commands.md``, ``docs/measured.md``): its
command line writes it, or with ``--check`` writes nothing and exits 1 when the page on disk is stale."""

import argparse
import sys
from pathlib import Path

from course.core.impl import REPO_ROOT


def main(argv, page: Path, render, *, command: str, description: str, source: str) -> int:
    """Write ``render()`` to ``page``; ``--check``: exit 1, naming ``source`` and ``command``, when it differs."""
    parser = argparse.ArgumentParser(prog=command, description=description)
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 when the page is stale")
    args = parser.parse_args(argv)
    text = render()
    name = page.relative_to(REPO_ROOT)
    if args.check:
        if page.is_file() and page.read_text(encoding="utf-8") == text:
            return 0
        print(f"{name} is not the render of {source}: run `{command}`", file=sys.stderr)
        return 1
    page.write_text(text, encoding="utf-8")
    print(f"wrote {name}")
    return 0
