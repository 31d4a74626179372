"""``python -m notebooks.site``: build the course's website into ``out/site/html/`` (see the package's docstring).

    python -m notebooks.site --small              # the whole course, every lesson in its quick setting (make site)
    python -m notebooks.site                      # every lesson in its full setting (an hour or more)
    python -m notebooks.site --assignment ch2     # the chapters up to assignment ch2's
    python -m notebooks.site --only ch2 --small   # one chapter, its lesson in the quick setting
    python -m notebooks.site --source-url https://github.com/OWNER/REPO/blob/main   # link source files
"""

import argparse
import shutil
import sys
import time
from pathlib import Path

from course.core import chapters
from course.core.impl import REPO_ROOT
from notebooks.site import chapter_pages, lessons, pages, sphinx_config

#: where the site is built by default
DEFAULT_OUT = REPO_ROOT / "out" / "site"


def chosen_chapters(assignment: str | None = None, only=None, root: Path = REPO_ROOT) -> list:
    """The chapters on the site: all; those up to ``assignment``'s latest chapter; or those named ``only``."""
    picked = list(chapters.CHAPTERS)
    if assignment:
        from autograder.course_config import load

        handed = load(root / "autograder" / "course.toml").assignment(assignment)
        picked = list(chapters.up_to(list(handed.exercises) + list(handed.optional)))
    if only:
        picked = [chapters.chapter(name) for name in only if chapters.chapter(name) in picked]
    return picked


def _title(root: Path) -> str:
    from autograder.course_config import load

    return load(root / "autograder" / "course.toml").title or "The course"


def _toctree(caption: str, entries: list) -> str:
    return "\n".join(["", "```{toctree}", ":hidden:", f":caption: {caption}", "", *entries, "```", ""])


def build(out: Path = DEFAULT_OUT, assignment: str | None = None, only=None, small: bool = False,
          source_url: str | None = None, log=print) -> Path:
    """Build the site into ``out/html`` (sources staged in ``out/src``, executions cached in ``out/executed``);
    returns ``out/html/index.html``."""
    from notebooks import build as notebook_build

    out = Path(out)
    picked = chosen_chapters(assignment, only)
    lessons_of = {one.name: chapter_pages.lesson_of(one) for one in picked}
    notebooks = [REPO_ROOT / rel for rel in lessons_of.values() if rel]
    start = time.perf_counter()
    executed = lessons.executed([nb for nb in notebooks if nb in notebook_build.NOTEBOOKS], out / "executed",
                                small=small, log=log)
    log(f"lessons ready in {time.perf_counter() - start:.0f} s")
    staged = dict(pages.guide_pages())
    staged.update({rel: rel for rel in lessons_of.values() if rel})
    chapter_paths = {one.name: f"chapters/{one.name}.md" for one in picked}
    files = pages.stage_guides(staged, source_url)
    guides = [rel for rel in pages.guide_pages().values() if rel != "index.md"]
    for nb, path in executed.items():
        files[nb.relative_to(REPO_ROOT).as_posix()] = path.read_bytes()
    for one in picked:
        files[chapter_paths[one.name]] = chapter_pages.chapter_page(one, lessons_of[one.name], source_url).encode()
    files["index.md"] += (_toctree("Chapters", [p[:-3] for p in chapter_paths.values()])
                          + _toctree("Guides", [g[:-3] for g in guides])).encode()
    files["conf.py"] = sphinx_config.conf_text(_title(REPO_ROOT)).encode()
    src = out / "src"
    src.mkdir(parents=True, exist_ok=True)
    pages.sync(src, files)
    shutil.rmtree(out / "html", ignore_errors=True)  # no page of an earlier build (a later chapter) stays
    start = time.perf_counter()
    warnings = sphinx_config.run_sphinx(src, out / "html", out / "doctrees")
    (out / "html" / ".nojekyll").write_text("")  # GitHub Pages serves the folders starting with "_" as they are
    for line in warnings:
        log(line)
    log(f"sphinx: {len(warnings)} warning line(s), {time.perf_counter() - start:.0f} s; the site: {out / 'html'}")
    return out / "html" / "index.html"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m notebooks.site", description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(DEFAULT_OUT), metavar="DIR",
                        help="build into DIR/html (default: out/site), sources in DIR/src, executions in DIR/executed")
    parser.add_argument("--assignment", metavar="NAME", default=None,
                        help="only the chapters up to assignment NAME's (e.g. ch2): the site of the semester so far")
    parser.add_argument("--only", nargs="+", metavar="CHAPTER", default=None,
                        help="only these chapters (ch1 ... ch7, ch3b)")
    parser.add_argument("--small", action="store_true",
                        help="execute the lessons in their quick setting (notebooks.build --small)")
    parser.add_argument("--source-url", default=None, metavar="URL",
                        help="link the repository's files to URL/PATH (e.g. a repository's blob/main); "
                             "without it they are plain text")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    try:
        index = build(Path(args.out), args.assignment, args.only, args.small, args.source_url,
                      log=lambda line: print(line, file=sys.stderr, flush=True))
    except (lessons.LessonError, KeyError, ValueError, RuntimeError) as exc:  # ValueError: the course configuration
        print(f"error: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 1
    print(f"built {index} in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
