"""Pairs of students whose code for one exercise file is unusually similar.

Method: our own token n-grams, no dependency. Each file is tokenized with Python's
:mod:`tokenize` (read as text, never imported: submissions are untrusted); comments, blank
lines, indentation and docstrings are dropped, every identifier that is not a keyword, a
builtin or an attribute name becomes ``N`` and every string ``S``, so renamed variables and
rewritten comments change nothing. A file is the set of its ``NGRAM``-token windows (plain
n-gram sets rather than winnowing: a class's exercise files are small, so keeping every
n-gram costs little and makes the containment exact). Then what every student would share
is discounted: the n-grams of the shipped stub (docstrings, signatures, hints), of the
reference solution when one is given (a correct answer is not evidence that two students
copied each other), and those found in at least ``COMMON_FRACTION`` of the class's written
submissions of that file and in at least ``COMMON_MIN_STUDENTS`` of them (the lines that
many correct students write alike; without a reference this is what discounts it, so in a
class of a few students, two correct ones may be flagged). Two students are compared on
what remains: the score is the containment ``|A & B| / min(|A|, |B|)``.

A pair is flagged when the score is high in absolute terms (``>= MIN_CONTAINMENT`` over at
least ``MIN_SHARED`` shared n-grams, so two tiny leftovers, such as the same one-line slip,
never flag) and an outlier among all the pairs of that file (above their median plus
``OUTLIER_MADS`` scaled median absolute deviations; with fewer than ``MIN_PAIRS`` pairs the
absolute rule alone decides). Unwritten stubs (byte-identical to the stub) are never
compared. Code that does not tokenize is split into words and symbols instead, and a note
says so.

Why not copydetect 0.5.0 (winnowing, with boilerplate directories)? It adds jinja2 and
pygments, declares Python up to 3.12 only, and flags on one global threshold; here the
discounting (stub, reference, class-common code), the per-file outlier test and the line
mapping for the report are a couple of hundred lines we control, with no dependency.

A leaked solution: discounting the reference hides the students who hand it in nearly unchanged,
alone or several of them. So each written file is also held against the reference's solution
code alone (the lines between ``# BEGIN SOLUTION`` and ``# END SOLUTION`` of ``solutions/NAME.py``,
the stub's n-grams taken out): a file that holds at least ``LEAK_CONTAINMENT`` of those n-grams is
flagged (:class:`Leak`), where the solution has at least ``LEAK_MIN_GRAMS`` of them (a solution of
a few lines is written alike by students who never saw it). The same normalisation applies, so
renaming the variables and rewriting the comments hide nothing.

Similarity is a prompt to look at two submissions, not a verdict.
"""

import builtins
import io
import keyword
import re
import tokenize
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

#: tokens per n-gram
NGRAM = 8
#: a flagged pair shares at least this share of the smaller file's remaining n-grams...
MIN_CONTAINMENT = 0.6
#: ... and at least this many remaining n-grams
MIN_SHARED = 25
#: ... and its score exceeds the median of the file's pairs by this many scaled MADs
OUTLIER_MADS = 4.0
#: the outlier test needs at least this many pairs of a file (3 written submissions)
MIN_PAIRS = 3
#: n-grams in at least this share of the written submissions of a file (and in at least
#: COMMON_MIN_STUDENTS of them) are common to the class, not evidence
COMMON_FRACTION = 0.5
COMMON_MIN_STUDENTS = 3
#: larger files are not compared (an exercise file is a few kilobytes)
MAX_BYTES = 1_000_000
#: a file holding at least this share of the reference's solution n-grams reproduces the reference...
LEAK_CONTAINMENT = 0.8
#: ... where the solution has at least this many n-grams beyond the stub's
LEAK_MIN_GRAMS = 25
BEGIN, END = "# BEGIN SOLUTION", "# END SOLUTION"

_BUILTINS = frozenset(dir(builtins))
_SKIP = {tokenize.COMMENT, tokenize.NL, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING, tokenize.ENDMARKER}
_FSTRING_START = getattr(tokenize, "FSTRING_START", -1)
_FSTRING_END = getattr(tokenize, "FSTRING_END", -1)
_WORD = re.compile(r"[A-Za-z_]\w*|\d[\w.]*|\S")


@dataclass
class Fingerprint:
    """A file's normalised tokens (``(text, line)``), its n-grams in order, and how it was read."""

    tokens: list
    grams: list
    note: str = ""


@dataclass
class SimilarPair:
    """Two students' copies of ``file``: the score, the number of shared n-grams and the
    line ranges ``(first, last)`` (1-based, inclusive) of each file that the shared n-grams cover."""

    a: str
    b: str
    file: str
    score: float
    shared: int
    lines_a: list
    lines_b: list


@dataclass
class Leak:
    """A student's ``file`` that reproduces the reference's solution: the share of the solution's
    n-grams it holds (``score``), how many (``shared``) of how many (``total``), and the line ranges
    of the student's file they cover."""

    student: str
    file: str
    score: float
    shared: int
    total: int
    lines: list


@dataclass
class FileStats:
    """One exercise file across the class: the students who wrote it, every pair's score
    (``{(a, b): score}``) and shared n-grams (``{(a, b): count}``), and the outlier bar used."""

    file: str
    written: list
    scores: dict
    shared: dict
    median: float
    mad: float
    bar: float


@dataclass
class Comparison:
    """The flagged pairs, per-file statistics and notes (files that did not tokenize)."""

    pairs: list
    files: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    reference_used: bool = False
    leaks: list = field(default_factory=list)


def _normalise(kind: int, text: str, previous: str) -> str:
    if kind == tokenize.NAME:
        if keyword.iskeyword(text) or text in _BUILTINS or previous == ".":
            return text
        return "N"
    if kind == tokenize.STRING or kind == _FSTRING_START:
        return "S"
    if kind == tokenize.NEWLINE:
        return ";"
    return text


def _python_tokens(text: str) -> list:
    """Normalised ``(token, line)`` of Python source, without comments and docstrings."""
    raw = []
    depth = 0  # inside an f-string (Python 3.12+ tokenizes its parts): one S, as older Pythons give
    for t in tokenize.generate_tokens(io.StringIO(text).readline):
        if depth:
            depth += (t.type == _FSTRING_START) - (t.type == _FSTRING_END)
        elif t.type not in _SKIP:
            raw.append(t)
            depth = int(t.type == _FSTRING_START)
    out: list = []
    i = 0
    while i < len(raw):
        tok = raw[i]
        statement_start = not out or out[-1][0] == ";"
        nxt = raw[i + 1] if i + 1 < len(raw) else None
        if tok.type == tokenize.STRING and statement_start and (nxt is None or nxt.type == tokenize.NEWLINE):
            i += 2  # a docstring (or a bare string statement) and its NEWLINE
            continue
        previous = raw[i - 1].string if i else ""
        out.append((_normalise(tok.type, tok.string, previous), tok.start[0]))
        i += 1
    return out


def _plain_tokens(text: str) -> list:
    """The fallback for code that does not tokenize: words and symbols, line by line."""
    out: list = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0]
        previous = ""
        for m in _WORD.finditer(line):
            word = m.group()
            if word[0].isalpha() or word[0] == "_":
                word = word if keyword.iskeyword(word) or word in _BUILTINS or previous == "." else "N"
            out.append((word, number))
            previous = m.group()
        if out and out[-1][1] == number:
            out.append((";", number))
    return out


def fingerprint(text: str) -> Fingerprint:
    """The n-grams of ``text``; falls back to a plain word split when it is not valid Python."""
    note = ""
    try:
        tokens = _python_tokens(text)
    except (tokenize.TokenError, SyntaxError, ValueError) as exc:
        tokens = _plain_tokens(text)
        note = f"does not tokenize as Python ({type(exc).__name__}: {exc}); compared as plain words and symbols"
    texts = [t for t, _ in tokens]
    grams = [hash(tuple(texts[i:i + NGRAM])) for i in range(len(texts) - NGRAM + 1)]
    return Fingerprint(tokens, grams, note)


def _read(path: Path) -> str:
    return path.read_bytes().decode("utf-8", errors="replace")


def _ranges(lines: set) -> list:
    """Sorted line numbers as ``(first, last)`` runs."""
    runs: list = []
    for n in sorted(lines):
        if runs and n == runs[-1][1] + 1:
            runs[-1][1] = n
        else:
            runs.append([n, n])
    return [tuple(r) for r in runs]


def _covered(fp: Fingerprint, shared: set) -> list:
    lines: set = set()
    for i, gram in enumerate(fp.grams):
        if gram in shared:
            lines.update(line for _, line in fp.tokens[i:i + NGRAM])
    return _ranges(lines)


def solution_lines(text: str) -> set:
    """The line numbers (1-based) between the ``# BEGIN SOLUTION`` and ``# END SOLUTION`` markers."""
    inside, lines = False, set()
    for number, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith(BEGIN):
            inside = True
        elif stripped.startswith(END):
            inside = False
        elif inside:
            lines.add(number)
    return lines


def solution_grams(reference_text: str, given=frozenset()) -> set:
    """The n-grams of the reference's solution blocks (every token of the n-gram inside a block),
    without those in ``given`` (the stub's)."""
    fp = fingerprint(reference_text)
    inside = solution_lines(reference_text)
    return {gram for i, gram in enumerate(fp.grams)
            if all(line in inside for _, line in fp.tokens[i:i + NGRAM])} - set(given)


def outlier_bar(scores: list) -> tuple:
    """``(median, scaled MAD, bar)`` of one file's pair scores: a pair must score above the bar
    (median + ``OUTLIER_MADS`` MADs scaled to a normal's standard deviation). With fewer than
    ``MIN_PAIRS`` pairs there is no class to stand out from: the bar is 0 and the absolute rule decides."""
    values = np.asarray(scores, dtype=float)
    if values.size == 0:
        return 0.0, 0.0, 0.0
    median = float(np.median(values))
    mad = 1.4826 * float(np.median(np.abs(values - median)))
    return median, mad, (median + OUTLIER_MADS * mad if values.size >= MIN_PAIRS else 0.0)


def _students(submissions_dir: Path) -> list:
    return sorted(p for p in Path(submissions_dir).iterdir() if p.is_dir())


def _exercise_files(stubs_dir: Path) -> list:
    return sorted(p.name for p in Path(stubs_dir).glob("*.py") if p.name != "__init__.py")


def compare_class(submissions_dir, stubs_dir, reference_dir=None) -> Comparison:
    """Compare every pair of written submissions of every exercise file of ``stubs_dir``."""
    result = Comparison(pairs=[], reference_used=reference_dir is not None)
    students = _students(Path(submissions_dir))
    for name in _exercise_files(Path(stubs_dir)):
        stub_bytes = (Path(stubs_dir) / name).read_bytes()
        given = set(fingerprint(stub_bytes.decode("utf-8", errors="replace")).grams)
        solution: set = set()
        if reference_dir is not None and (Path(reference_dir) / name).is_file():
            reference_text = _read(Path(reference_dir) / name)
            solution = solution_grams(reference_text, given)
            given |= set(fingerprint(reference_text).grams)
        prints: dict = {}
        seen: dict = {}
        for folder in students:
            path = folder / name
            if path.is_symlink() or not path.is_file():
                continue
            if path.stat().st_size > MAX_BYTES:
                result.notes.append(f"{folder.name}/{name} is larger than {MAX_BYTES} bytes: not compared")
                continue
            data = path.read_bytes()
            if data == stub_bytes:
                continue  # not sent: the unwritten stub
            if data not in seen:  # many students hand in the same file (often the reference's)
                seen[data] = fingerprint(data.decode("utf-8", errors="replace"))
            fp = seen[data]
            if fp.note:
                result.notes.append(f"{folder.name}/{name} {fp.note}")
            prints[folder.name] = fp
        if len(solution) >= LEAK_MIN_GRAMS:
            for sid, fp in sorted(prints.items()):
                held = set(fp.grams) & solution
                if len(held) >= LEAK_CONTAINMENT * len(solution):
                    result.leaks.append(Leak(sid, name, len(held) / len(solution), len(held), len(solution),
                                             _covered(fp, held)))
        remaining = {sid: set(fp.grams) - given for sid, fp in prints.items()}
        counts: dict = {}
        for grams in remaining.values():
            for gram in grams:
                counts[gram] = counts.get(gram, 0) + 1
        floor = max(COMMON_MIN_STUDENTS, COMMON_FRACTION * len(remaining))
        common = {gram for gram, n in counts.items() if n >= floor}
        remaining = {sid: grams - common for sid, grams in remaining.items()}
        ids = sorted(remaining)
        scores: dict = {}
        shared_sets: dict = {}
        for i, a in enumerate(ids):
            for b in ids[i + 1:]:
                shared = remaining[a] & remaining[b]
                smaller = min(len(remaining[a]), len(remaining[b]))
                scores[(a, b)] = len(shared) / smaller if smaller else 0.0
                shared_sets[(a, b)] = shared
        median, mad, bar = outlier_bar(list(scores.values()))
        counts_shared = {pair: len(grams) for pair, grams in shared_sets.items()}
        result.files[name] = FileStats(name, ids, scores, counts_shared, median, mad, bar)
        for (a, b), score in scores.items():
            shared = shared_sets[(a, b)]
            if score >= MIN_CONTAINMENT and len(shared) >= MIN_SHARED and score > bar:
                result.pairs.append(SimilarPair(a, b, name, score, len(shared),
                                                _covered(prints[a], shared), _covered(prints[b], shared)))
    result.pairs.sort(key=lambda p: (-p.score, p.file, p.a, p.b))
    result.leaks.sort(key=lambda leak: (leak.file, -leak.score, leak.student))
    return result


def leaked(submissions_dir, stubs_dir, reference_dir) -> list:
    """The :class:`Leak` records: files that reproduce the reference's solution code."""
    return compare_class(submissions_dir, stubs_dir, reference_dir).leaks


def similar_pairs(submissions_dir, stubs_dir, reference_dir=None) -> list:
    """The flagged :class:`SimilarPair` records, most similar first (see the module docstring)."""
    return compare_class(submissions_dir, stubs_dir, reference_dir).pairs
