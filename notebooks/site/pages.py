"""The guides staged for Sphinx: ``README.md`` as ``index.md``, every ``docs/*.md`` as it is, their links
rewritten.

The site keeps the repository's layout (``docs/X.md``, ``notebooks/chapterN_*.ipynb``), so a link
between two staged pages stays as written, but for ``README.md``, which is ``index.md`` on the site.
A link to any other file or folder of the repository (``course/app/compare.py``, ``CONTRIBUTING.md``,
``docs/measured/``) becomes a link to it at the source URL (``SOURCE_URL/PATH``) when one is given,
else its text alone. Web addresses and a page's own anchors (``#section``) stay. Fenced code blocks
and inline code are left as they are.
"""

import posixpath
import re
from pathlib import Path

from course.core.impl import REPO_ROOT

#: ``[text](target "title")`` and ``![alt](target)``: a markdown inline link or image
LINK = re.compile(r"(?P<bang>!?)\[(?P<text>(?:[^\[\]\n]|\[[^\[\]\n]*\])*)\]"
                  r"\((?P<target>[^()\s]+)(?P<title>\s+\"[^\"]*\")?\)")
#: ``` or ~~~ opening or closing a fenced block
FENCE = re.compile(r"^\s*(```|~~~)")
#: inline code spans, left untouched
CODE_SPAN = re.compile(r"(?P<ticks>`+)(?:(?!(?P=ticks)).)+?(?P=ticks)")
#: a link (whose text may hold code spans) or a code span, whichever starts first
LINK_OR_CODE = re.compile(f"{LINK.pattern}|{CODE_SPAN.pattern}")


def guide_pages(root: Path = REPO_ROOT) -> dict:
    """``{repository path: site path}`` of the guides: ``README.md`` -> ``index.md`` and each
    ``docs/*.md`` there is now (listed, not named: new pages come in by themselves)."""
    pages = {"README.md": "index.md"}
    pages.update({f"docs/{path.name}": f"docs/{path.name}" for path in sorted((root / "docs").glob("*.md"))})
    return pages


def _is_external(target: str) -> bool:
    return bool(re.match(r"^[a-zA-Z][a-zA-Z0-9+.-]*:", target)) or target.startswith("//")


def rewrite_link(target: str, page: str, staged: dict, source_url: str | None) -> str | None:
    """The link ``target`` of the page at repository path ``page`` as the site has it: relative to the
    page's site path when it points to a staged page, ``source_url/PATH`` for another file of the
    repository, unchanged for a web address or an anchor; None: no link (keep the text alone)."""
    if _is_external(target) or target.startswith("#"):
        return target
    path, hash_, anchor = target.partition("#")
    repo_path = posixpath.normpath(posixpath.join(posixpath.dirname(page), path))
    if repo_path in staged:
        here = posixpath.dirname(staged[page]) or "."
        return posixpath.relpath(staged[repo_path], here) + hash_ + anchor
    if repo_path.startswith("../") or repo_path == "..":
        return None  # outside the repository
    if source_url:
        return f"{source_url.rstrip('/')}/{repo_path}" + hash_ + anchor
    return None


def rewrite_links(text: str, page: str, staged: dict, source_url: str | None = None) -> str:
    """``text`` (markdown of the page at repository path ``page``) with every link rewritten by
    :func:`rewrite_link` outside fenced blocks and code spans."""
    out, fenced = [], None
    for line in text.splitlines(keepends=True):
        fence = FENCE.match(line)
        if fenced is not None:
            if fence and fence.group(1) == fenced:
                fenced = None
            out.append(line)
            continue
        if fence:
            fenced = fence.group(1)
            out.append(line)
            continue
        out.append(_rewrite_line(line, page, staged, source_url))
    return "".join(out)


def _rewrite_line(line: str, page: str, staged: dict, source_url: str | None) -> str:
    def one(match):
        target = rewrite_link(match["target"], page, staged, source_url)
        if target is None:
            return match["text"] if not match["bang"] else match["text"] or ""
        return f"{match['bang']}[{match['text']}]({target}{match['title'] or ''})"

    # links outside code spans only; a link's text may hold code spans ([`name`](target))
    return LINK_OR_CODE.sub(lambda match: one(match) if match["target"] else match.group(0), line)


def stage_guides(staged: dict, source_url: str | None, root: Path = REPO_ROOT) -> dict:
    """``{site path: content}`` of each guide of ``guide_pages``, links rewritten against ``staged`` (every
    page the site has; an image of the repository a guide shows is added to it, and to the result)."""
    files: dict = {}
    for repo_path, site_path in guide_pages(root).items():
        text = (root / repo_path).read_text(encoding="utf-8")
        for match in LINK.finditer(text):  # an image of the repository is copied beside the page
            image = posixpath.normpath(posixpath.join(posixpath.dirname(repo_path), match["target"].partition("#")[0]))
            if match["bang"] and not _is_external(match["target"]) and (root / image).is_file() \
                    and not image.startswith("../"):
                files[image] = (root / image).read_bytes()
                staged.setdefault(image, image)
        files[site_path] = rewrite_links(text, repo_path, staged, source_url).encode("utf-8")
    return files


def sync(src: Path, files: dict) -> None:
    """Make the folder ``src`` hold ``files`` (``{relative path: bytes}``) and nothing else, writing only the
    files whose content changed (Sphinx reads again only those)."""
    for rel, content in files.items():
        target = src / rel
        if not (target.is_file() and target.read_bytes() == content):
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(content)
    for path in sorted(src.rglob("*"), reverse=True):
        rel = path.relative_to(src).as_posix()
        if path.is_file() and rel not in files:
            path.unlink()
        elif path.is_dir() and not any(path.iterdir()):
            path.rmdir()
