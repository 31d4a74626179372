"""Every command a page shows runs in a test: the lines of the shell blocks (```bash, ```sh, ```shell,
```console) of README.md and of every docs/*.md are either run here, in order, from a working folder
of their own, or claimed by a named other test (:data:`RUN_ELSEWHERE`) that runs them, which must
exist and read that page or run that command. The README's front door stays short, and links each
guide page; every relative link of every page resolves, its anchor too."""

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from course.core.impl import REPO_ROOT

PAGES = [REPO_ROOT / "README.md", *sorted((REPO_ROOT / "docs").glob("*.md"))]
SHELLS = ("bash", "sh", "shell", "console")
#: (page, a regular expression a command matches, the test that runs it, a string that test's source holds)
RUN_ELSEWHERE = (
    ("docs/teaching.md", r"^python -m ", "tests/test_teaching_guide.py", "docs\" / \"teaching.md"),
    ("docs/teaching.md", r"^docker ", "tests/test_grading_image.py", "docs\" / \"teaching.md"),
    # the zip tried as Gradescope runs it: unpacked into ROOT/source, the upload in ROOT/submission
    ("docs/teaching.md", r"^(mkdir -p /tmp/ag/submission|cp my_answers|AUTOGRADER_ROOT=)",
     "tests/test_gradescope_bundle.py", "run_autograder"),
    ("docs/measured.md", r"^python -m course benchmark --suite ", "tests/test_benchmark_suite.py",
     "docs\" / \"measured.md"),
    # the site built for chapter 2 into the test's folder, and served on a free port until it answers
    ("docs/site.md", r"^python -m (notebooks\.site|http\.server) ", "tests/test_site.py", "docs\" / \"site.md"),
    # CI's command (.ci/run); here its recipe is checked by a dry run (test_the_readme_s_make_targets)
    ("README.md", r"^make test$", ".ci/run", "make test"),
)
MAX_README_LINES = 150


def shell_commands(page: Path) -> list:
    """The commands of the page's shell blocks: one per line, continuation lines joined, comments kept."""
    text = page.read_text(encoding="utf-8")
    blocks = re.findall(r"^```(\w+)\n(.*?)^```", text, re.S | re.M)
    commands = []
    for language, block in blocks:
        if language in SHELLS:
            joined = re.sub(r"\\\n\s*", "", block)
            commands += [line.strip() for line in joined.splitlines() if line.strip()]
    return commands


def bare(command: str) -> str:
    """The command without its trailing ``# comment``."""
    return re.sub(r"\s+#\s.*$", "", command)


def claimed(page: str, command: str):
    """The :data:`RUN_ELSEWHERE` entry that claims ``command`` of ``page``, or None."""
    return next((entry for entry in RUN_ELSEWHERE if entry[0] == page and re.search(entry[1], bare(command))), None)


def run_here() -> list:
    """``(page, command)`` of every command that no other test claims, in page order."""
    return [(page.relative_to(REPO_ROOT).as_posix(), command) for page in PAGES for command in shell_commands(page)
            if not claimed(page.relative_to(REPO_ROOT).as_posix(), command)]


def test_every_command_of_every_page_is_run_by_a_test():
    shown = {page.relative_to(REPO_ROOT).as_posix(): shell_commands(page) for page in PAGES}
    assert shown["README.md"] == ["make demo   # creates .venv, installs the package, runs the comparison on "
                                  "generated data",
                                  "make test   # creates or refreshes .venv, runs ruff, mypy and the whole test suite"]
    for page, command, test, mark in RUN_ELSEWHERE:
        assert (REPO_ROOT / test).is_file(), test
        assert mark in (REPO_ROOT / test).read_text(encoding="utf-8"), f"{test} does not run {page}'s commands"
        assert any(re.search(command, bare(line)) for line in shown[page]), f"{page} no longer shows {command}"
    for page, command in run_here():
        words = shlex.split(command, comments=True)
        assert words[0] in (".venv/bin/python", "python") or words == ["make", "demo"], (
            f"{page}: this test cannot run `{command}`: claim it in RUN_ELSEWHERE with the test that runs it")


def test_the_readme_s_make_targets():
    """``make demo`` runs the demo (``tests/test_cli.py`` runs ``course demo`` itself) and ``make test``
    the linters and the whole suite; both set up ``.venv`` first: their dry runs say so."""
    make = "make"
    for target, needs in (("demo", ["-m course demo"]), ("test", ["-m ruff check", "-m mypy", "lint-imports",
                                                                  "-m pytest"])):
        done = subprocess.run([make, "-n", "-B", target], cwd=REPO_ROOT, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        assert "-m venv .venv" in done.stdout and "pip install" in done.stdout, (target, done.stdout)
        assert all(need in done.stdout for need in needs), (target, done.stdout)


@pytest.mark.slow
def test_every_command_not_claimed_elsewhere_runs(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    ran = 0
    for page, command in run_here():
        words = shlex.split(command, comments=True)
        if words == ["make", "demo"]:
            continue  # its recipe: test_the_readme_s_make_targets; `course demo` itself: tests/test_cli.py
        argv = [sys.executable, *words[1:]]
        done = subprocess.run(argv, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900)
        assert done.returncode == 0, f"{page}: {command}\n{done.stdout[-2000:]}\n{done.stderr[-2000:]}"
        ran += 1
    assert ran >= 6
    assert (tmp_path / "results.json").is_file() and (tmp_path / "out" / "intel.png").is_file()


def test_the_readme_is_a_front_door_linking_each_guide():
    readme = (REPO_ROOT / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= MAX_README_LINES
    targets = set(re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", readme))
    guides = {page.relative_to(REPO_ROOT).as_posix() for page in PAGES[1:]}
    assert guides <= targets, f"the README does not link {sorted(guides - targets)}"
    assert "CONTRIBUTING.md" in targets


def anchors(page: Path) -> set:
    """The anchors of a page's headings, as GitHub makes them."""
    out = set()
    for heading in re.findall(r"^#+ (.*)$", re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"),
                                                     flags=re.S | re.M), re.M):
        out.add(re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-"))
    return out


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(REPO_ROOT).as_posix())
def test_every_relative_link_resolves(page):
    text = re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"\w+://|mailto:", target):
            continue
        path, _, anchor = target.partition("#")
        resolved = (page.parent / path).resolve() if path else page
        name = resolved.relative_to(REPO_ROOT).as_posix() if resolved.is_relative_to(REPO_ROOT) else str(resolved)
        assert resolved.exists(), f"{page.relative_to(REPO_ROOT)}: the link {target} resolves to nothing"
        if anchor and resolved.suffix == ".md":
            assert anchor in anchors(resolved), f"{page.relative_to(REPO_ROOT)}: no heading for #{anchor} in {name}"
