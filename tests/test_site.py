"""The course's website (``python -m notebooks.site``, ``make site``): built from the guides and chapter 2's
lesson, it gives away no answer, loads nothing from the network, and reads right in a real browser.

The suite builds one chapter (``--only ch2 --small``); ``make site`` builds every chapter in the full
setting. The lesson's execution is the one ``tests/executed_notebooks.py`` already made for this test
run (the small setting, shared with ``test_notebooks.py`` and ``test_lesson_2.py``), put into the site's
cache under the key a build looks for, so that the suite runs the lesson once; the student tree the
build itself executes in is tested apart (``test_the_student_tree_holds_no_hint_and_no_solutions``).

The browser is Debian's headless Chromium through its chromedriver (``/usr/bin/chromedriver``, given
to selenium: nothing is downloaded), resolving no host name but this machine's, with the site served
over HTTP from a local port as a static host serves it. Screenshots land in ``out/site-test/screenshots/``.
"""

import html
import os
import re
import shutil
import subprocess
import sys
import threading
import urllib.request
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

import nbformat
import pytest

pytest.importorskip("sphinx", reason="the site extra is not installed: pip install -e '.[site]'")
pytest.importorskip("myst_nb", reason="the site extra is not installed: pip install -e '.[site]'")

from course.core.impl import REPO_ROOT  # noqa: E402
from notebooks import build as notebook_build  # noqa: E402
from notebooks.site import __main__ as site  # noqa: E402
from notebooks.site import lessons, pages  # noqa: E402

OUT = REPO_ROOT / "out" / "site-test"
CHROMIUM = shutil.which("chromium") or "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
GUIDE = REPO_ROOT / "docs" / "site.md"
#: hosts a page could load a library from instead of carrying it
CDN = re.compile(r"cdn\.|jsdelivr|unpkg|cdnjs|mathjax\.org|googleapis|gstatic|bootstrapcdn|require\.js", re.I)


def _seed_cache(out: Path) -> None:
    from executed_notebooks import executed_small

    nb = notebook_build.CHAPTER2
    key = lessons.cache_key(nb, True, lessons.sources_digest())
    target = out / "executed" / f"{nb.stem}-{key}.ipynb"
    if not target.is_file():
        target.parent.mkdir(parents=True, exist_ok=True)
        nbformat.write(executed_small(nb), target)


@pytest.fixture(scope="module")
def built():
    shutil.rmtree(OUT / "html", ignore_errors=True)
    _seed_cache(OUT)
    lines: list = []
    index = site.build(OUT, only=["ch2"], small=True, log=lines.append)
    assert index == OUT / "html" / "index.html" and index.is_file()
    return OUT / "html", lines


def _pages(root: Path) -> list:
    return sorted(p for p in root.rglob("*.html") if "_static" not in p.parts)


def _text(path: Path) -> str:
    """The page's text: tags dropped, entities decoded, whitespace folded."""
    raw = path.read_text(encoding="utf-8")
    raw = re.sub(r"<(script|style)\b.*?</\1>", " ", raw, flags=re.S)
    return " ".join(html.unescape(re.sub(r"<[^>]+>", " ", raw)).split())


def test_the_site_has_the_index_the_guides_the_chapter_and_its_lesson(built):
    root, lines = built
    for rel in pages.guide_pages().values():
        assert (root / (rel[:-3] + ".html")).is_file(), rel
    assert (root / "chapters" / "ch2.html").is_file()
    assert (root / "notebooks" / "chapter2_pose_graphs.html").is_file()
    assert not (root / "chapters" / "ch1.html").exists()  # --only ch2
    assert any("executed before" in line for line in lines), lines  # the seeded execution was used
    chapter = (root / "chapters" / "ch2.html").read_text()
    assert "chapter2_pose_graphs.html" in chapter and "Hint 2" in chapter and "Hint 3" not in chapter
    assert "The assignment" in chapter and "Due:" in chapter


def test_nothing_is_loaded_from_elsewhere(built):
    root, _ = built
    for page in _pages(root):
        raw = page.read_text(encoding="utf-8")
        loaded = re.findall(r"<(?:script|link|img|iframe|source)\b[^>]*?(?:src|href)=\"([^\"]+)\"", raw)
        remote = [url for url in loaded if re.match(r"^(https?:)?//", url)]
        assert not remote, (page.relative_to(root), remote)
        urls = re.findall(r"(?:https?:)?//[\w.-]+[^\s\"'<>)]*", raw)
        assert not [u for u in urls if CDN.search(u)], (page.relative_to(root), [u for u in urls if CDN.search(u)])
    mathjax = root / "_static" / "mathjax" / "tex-chtml.js"
    assert mathjax.is_file() and 'src="../_static/mathjax/tex-chtml.js"' in (
        root / "notebooks" / "chapter2_pose_graphs.html").read_text()


def _solution_lines() -> list:
    """The reference's own lines: each line (25 characters or more, not a comment) between
    ``# BEGIN SOLUTION`` and ``# END SOLUTION`` in solutions/*.py that the stubs do not hold too."""
    found = []
    for path in sorted((REPO_ROOT / "solutions").glob("*.py")):
        stub_path = REPO_ROOT / "exercises" / path.name
        stub = stub_path.read_text() if stub_path.is_file() else ""
        inside = False
        for line in path.read_text().splitlines():
            if "# BEGIN SOLUTION" in line:
                inside = True
            elif "# END SOLUTION" in line:
                inside = False
            elif inside:
                code = line.strip()
                if len(code) >= 25 and not code.startswith("#") and code not in stub:
                    found.append((path.name, code))
    return found


def _level_3_lines() -> list:
    """Each line (25 characters or more) of every exercise's level-3 hints, without reST marks."""
    from autograder.hints import hint_sources

    found = []
    for exercise, owners in hint_sources().items():
        for owner, levels in owners.items():
            others = " ".join(" ".join(level.replace("``", "").split()) for level in levels[:2])
            for line in levels[2].splitlines():
                line = " ".join(line.replace("``", "").strip(" :").split())
                if len(line) >= 25 and line not in others:  # a line that hint 1 or 2 also says may show
                    found.append((exercise, owner, line))
    return found


def test_no_level_3_hint_and_no_solution_code_on_the_site(built):
    root, _ = built
    text = "\n".join(_text(page) for page in _pages(root))
    text += "\n".join(" ".join(p.read_text(encoding="utf-8", errors="replace").split())
                      for p in root.rglob("*") if p.is_file() and p.suffix in (".txt", ".ipynb", ".py", ".js", ".md")
                      and "_static" not in p.parts)
    hints, code = _level_3_lines(), _solution_lines()
    assert len(hints) > 50 and len(code) > 100  # the scan looks for something
    assert [h for h in hints if h[2] in text] == []
    assert [c for c in code if " ".join(c[1].split()) in text] == []


def test_the_student_tree_holds_no_hint_and_no_solutions(tmp_path):
    tree = lessons.write_student_tree(tmp_path / "tree")
    assert not (tree / "solutions").exists() and (tree / "notebooks" / "chapter2_pose_graphs.ipynb").is_file()
    edge = (tree / "exercises" / "pose_graph_edge.py").read_text()
    assert "NotImplementedError" not in edge and "HINTS" not in edge  # the reference, its hints taken out
    assert "# BEGIN SOLUTION" in (REPO_ROOT / "solutions" / "pose_graph_edge.py").read_text()


def test_links_are_rewritten_for_the_site():
    staged = {"README.md": "index.md", "docs/teaching.md": "docs/teaching.md",
              "notebooks/chapter2_pose_graphs.ipynb": "notebooks/chapter2_pose_graphs.ipynb"}
    text = ("See [the guide](docs/teaching.md#grading), [the lesson](notebooks/chapter2_pose_graphs.ipynb), "
            "[compare](course/app/compare.py), [a site](https://example.org) and [below](#layout).\n"
            "```bash\n[not a link](course/x.py)\n```\n`[code](course/y.py)`\n")
    plain = pages.rewrite_links(text, "README.md", staged)
    assert "[the guide](docs/teaching.md#grading)" in plain and "compare," in plain
    assert "[a site](https://example.org)" in plain and "[below](#layout)" in plain
    assert "[not a link](course/x.py)" in plain and "`[code](course/y.py)`" in plain
    linked = pages.rewrite_links(text, "README.md", staged, "https://host/repo/blob/main")
    assert "[compare](https://host/repo/blob/main/course/app/compare.py)" in linked
    back = pages.rewrite_links("[home](../README.md), [peer](peers.md)", "docs/teaching.md",
                               {**staged, "docs/peers.md": "docs/peers.md"})
    assert back == "[home](../index.md), [peer](peers.md)"


# --- in the browser ---------------------------------------------------------------------------------------------


def _browser_missing() -> str | None:
    if not (Path(CHROMIUM).is_file() and Path(CHROMEDRIVER).is_file()):
        return f"no headless browser here ({CHROMIUM}, {CHROMEDRIVER}): apt-get install chromium chromium-driver"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium is not installed: pip install -e '.[site]'"
    return None


@pytest.fixture(scope="module")
def served(built):
    root, _ = built

    class Quiet(SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), partial(Quiet, directory=str(root)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield root, f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.fixture(scope="module")
def browser():
    reason = _browser_missing()
    if reason:
        pytest.skip(reason)
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--disable-gpu",
                 "--window-size=1280,1600", "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1"):
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=CHROMEDRIVER), options=options)
    driver.set_page_load_timeout(60)
    driver.set_script_timeout(60)
    yield driver
    driver.quit()


#: waits for MathJax's first typesetting, then reports what the test reads
READ_PAGE = """
const done = arguments[arguments.length - 1];
const ready = (window.MathJax && MathJax.startup && MathJax.startup.promise) || Promise.resolve();
ready.then(() => {
  const maths = Array.from(document.querySelectorAll('.math'));
  done({
    text: document.body.innerText,
    maths: maths.length,
    typeset: maths.filter(m => m.querySelector('mjx-container')).length,
    images: Array.from(document.images).map(i => [i.getAttribute('src'), i.complete && i.naturalWidth > 0]),
    links: Array.from(document.querySelectorAll('a[href]')).map(a => a.href),
  });
}).catch(e => done({error: String(e)}));
"""


#: scrolls the page to its first figure (at once: the theme scrolls smoothly otherwise)
SHOW_FIRST_FIGURE = """
const image = document.querySelector('article img') || document.images[0];
window.scrollTo({top: image.getBoundingClientRect().top + window.scrollY - 80, behavior: 'instant'});
"""


def _ids(path: Path) -> set:
    return set(re.findall(r"\bid=\"([^\"]+)\"", path.read_text(encoding="utf-8")))


def test_every_page_reads_right_in_the_browser(served, browser):
    root, base = served
    shots = OUT / "screenshots"
    shots.mkdir(parents=True, exist_ok=True)
    wanted = [root / "index.html", *sorted((root / "notebooks").glob("*.html")),
              *sorted((root / "chapters").glob("*.html"))]
    assert root / "notebooks" / "chapter2_pose_graphs.html" in wanted
    for page in wanted:
        rel = page.relative_to(root).as_posix()
        browser.get(f"{base}/{rel}")
        seen = browser.execute_async_script(READ_PAGE)
        assert "error" not in seen, (rel, seen)
        assert "$$" not in seen["text"] and "\\begin" not in seen["text"], rel
        assert seen["typeset"] == seen["maths"], (rel, seen["maths"], seen["typeset"])
        assert all(ok for _, ok in seen["images"]), (rel, [src for src, ok in seen["images"] if not ok])
        for link in seen["links"]:
            parts = urlsplit(link)
            if f"{parts.scheme}://{parts.netloc}" != base:
                continue
            target = root / unquote(parts.path).lstrip("/")
            if target.is_dir():
                target = target / "index.html"
            assert target.is_file(), (rel, link)
            if parts.fragment and target.suffix == ".html":
                assert unquote(parts.fragment) in _ids(target), (rel, link)
        if page.parent.name == "notebooks":
            assert seen["maths"] > 20 and len(seen["images"]) >= 4, (rel, seen["maths"], seen["images"])
        name = rel.replace("/", "-")[:-5]
        browser.save_screenshot(str(shots / f"{name}.png"))
        if page.parent.name == "notebooks":  # and its first figure, in view
            browser.execute_script(SHOW_FIRST_FIGURE)
            browser.save_screenshot(str(shots / f"{name}-figure.png"))
    assert (shots / "index.png").stat().st_size > 10_000
    assert (shots / "notebooks-chapter2_pose_graphs.png").stat().st_size > 10_000


# --- the guide's commands ---------------------------------------------------------------------------------------


def _guide_commands() -> list:
    blocks = re.findall(r"```bash\n(.*?)```", GUIDE.read_text(), re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


def test_every_command_of_the_publishing_guide_runs(built):
    """Each ``python -m notebooks.site ...`` of docs/site.md runs on chapter 2 in the quick setting into the
    folder of the site built above (``--out``, ``--only ch2 --small`` added: the whole course takes minutes): the
    execution is cached there and Sphinx reads again only the pages that changed; ``python -m http.server ...``
    serves the site built (stopped once it answers)."""
    commands = _guide_commands()
    assert any(c.startswith("python -m notebooks.site") for c in commands)
    assert any(c.startswith("python -m http.server") for c in commands)
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    for line in commands:
        argv = [sys.executable] + line.split()[1:]
        if line.startswith("python -m notebooks.site"):
            out = OUT
            done = subprocess.run([*argv, "--out", str(out), "--only", "ch2", "--small"], cwd=REPO_ROOT, env=env,
                                  capture_output=True, text=True, timeout=600)
            assert done.returncode == 0, (line, done.stderr[-3000:])
            assert (out / "html" / "index.html").is_file()
            if "--source-url" in line:
                url = line.split("--source-url")[1].split()[0]
                assert f'href="{url}/' in (out / "html" / "chapters" / "ch2.html").read_text() or \
                    f'href="{url}/' in (out / "html" / "index.html").read_text()
        elif line.startswith("python -m http.server"):  # on a free port, serving the folder built above
            import socket

            with socket.socket() as probe:
                probe.bind(("127.0.0.1", 0))
                port = probe.getsockname()[1]
            argv = [str(port) if a.isdigit() else str(OUT / Path(a).relative_to("out/site"))
                    if a.startswith("out/site") else a for a in argv] + ["--bind", "127.0.0.1"]
            server = subprocess.Popen(argv, cwd=REPO_ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            try:
                for _ in range(100):
                    try:
                        with urllib.request.urlopen(f"http://127.0.0.1:{port}/index.html", timeout=2) as reply:
                            assert reply.status == 200
                            break
                    except OSError:
                        threading.Event().wait(0.1)
                else:
                    pytest.fail(f"{line}: nothing served on port {port}")
            finally:
                server.terminate()
                server.wait(10)
        else:
            pytest.fail(f"docs/site.md shows a command this test does not run: {line}")
