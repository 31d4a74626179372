"""The class report of a batch grading run (autograder.classroom), on a synthetic class.

The class is written in a temporary folder as ``python -m autograder batch`` leaves it: the
graded packages under ``submissions/<id>/`` (copies of the real ``solutions/`` and
``exercises/``, one-line slips from tests/student_variants) and hand-written results under
``results/<id>.json``. Nothing is graded here.
"""

import html
import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

from autograder.classroom import similarity  # noqa: E402
from autograder.classroom.report import write_report  # noqa: E402
from student_variants import VARIANTS, apply  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
STUBS, REFERENCE = ROOT / "exercises", ROOT / "solutions"
HIDDEN = " (hidden inputs)"

T1_DIAG = "damping.GavinType1: damping_diagonal"
T3_DIAG = "damping.GavinType3: damping_diagonal"
T3_RESET = "damping.GavinType3: update (accepted step, nu reset)"
R_VALUES = "curve_model.residuals_and_jacobian: r values"
J_VALUES = "curve_model.residuals_and_jacobian: J values"
STEP = "gauss_newton.solve_step: undamped step"
LM1 = "end_to_end: lm-type1"
#: (exercise, check, points): each graded on public and on hidden inputs
CHECKS = [("curve_model", R_VALUES, 2.0), ("curve_model", J_VALUES, 2.0), ("gauss_newton", STEP, 2.0),
          ("damping", T1_DIAG, 1.0), ("damping", T3_DIAG, 1.0), ("damping", T3_RESET, 1.0), ("end_to_end", LM1, 2.0)]
ALL = {name for _, name, _ in CHECKS}
DAMPING = {T1_DIAG, T3_DIAG, T3_RESET, LM1}

LAMBDA_I = "Type 1's lambda multiplies the identity where it should multiply diag(H)."
R_SIGN = "r has the opposite sign: r = y_hat - y."
H_SIGN = "h has the opposite sign: the step solves H h = -b."
NU_RESET = "nu is not reset to 2 after an accepted step."

# X's damping.py: correct, written otherwise than the reference (loops, early returns, other names)
X_BODIES = {
    "GavinType1.initial_state": "start = self.lambda_0\nreturn DampingState(lam=start)",
    "GavinType1.damping_diagonal": (
        "# scale each diagonal entry\nout = np.array(diag_H, dtype=float)\nfor k in range(out.size):\n"
        "    out[k] = out[k] * lam\nreturn out"),
    "GavinType1.gain_denominator": (
        "assert np.ndim(h) == 1, \"</table><script>alert('h must be 1-d')</script>\"\n"
        "scaled = lam * np.array(diag_H, dtype=float)\ntotal = 0.0\n"
        "for hk, sk, bk in zip(h, scaled, b):\n    total += hk * (sk * hk - bk)\nreturn float(total)"),
    "GavinType1.update": (
        "if not accepted:\n    new_lam = state.lam * self.l_up\n    if new_lam > LAMBDA_MAX:\n"
        "        new_lam = LAMBDA_MAX\n    return DampingState(lam=new_lam, nu=state.nu)\n"
        "new_lam = state.lam / self.l_down\nif new_lam < LAMBDA_MIN:\n    new_lam = LAMBDA_MIN\n"
        "return DampingState(lam=new_lam, nu=state.nu)"),
    "GavinType2.initial_state": "biggest = max(float(v) for v in diag_H)\nreturn DampingState(lam=biggest * self.tau)",
    "GavinType2.damping_diagonal": "return float(lam) * np.ones(np.size(diag_H))",
    "GavinType2.step_scale": (
        "# the slope along h\nslope = -float(np.dot(b, h))\nrise = 0.5 * (chi2_full_step - chi2)\n"
        "alpha = slope / (rise + 2.0 * slope)\nif alpha < ALPHA_MIN:\n    alpha = ALPHA_MIN\nreturn alpha"),
    "GavinType2.gain_denominator": "total = 0.0\nfor hk, bk in zip(h, b):\n    total += hk * (lam * hk - bk)\n"
                                   "return float(total)",
    "GavinType2.update": (
        "if not accepted:\n    grown = state.lam + abs(dchi2) / (alpha + alpha)\n"
        "    return DampingState(lam=grown, nu=state.nu)\nshrunk = state.lam / (alpha + 1.0)\n"
        "if shrunk < LAMBDA_MIN:\n    shrunk = LAMBDA_MIN\nreturn DampingState(lam=shrunk, nu=state.nu)"),
    "GavinType3.initial_state": "biggest = max(float(v) for v in diag_H)\n"
                                "return DampingState(lam=biggest * self.tau, nu=2.0)",
    "GavinType3.damping_diagonal": "return float(lam) * np.ones(np.size(diag_H))",
    "GavinType3.gain_denominator": "total = 0.0\nfor hk, bk in zip(h, b):\n    total += hk * (lam * hk - bk)\n"
                                   "return float(total)",
    "GavinType3.update": (
        "if not accepted:\n    return DampingState(lam=state.lam * state.nu, nu=state.nu * 2.0)\n"
        "cube = (2.0 * rho - 1.0) ** 3\nfactor = 1.0 - cube\nif factor < 1.0 / 3.0:\n    factor = 1.0 / 3.0\n"
        "return DampingState(lam=state.lam * factor, nu=2.0)"),
}
#: Y's renames of X's identifiers (word by word) and comments
Y_RENAMES = {"start": "lam_zero", "out": "diag", "k": "idx", "scaled": "weighted", "total": "acc", "hk": "hi",
             "sk": "si", "bk": "bi", "new_lam": "lam_new", "biggest": "top", "slope": "gh", "rise": "half_change",
             "grown": "bigger", "shrunk": "smaller", "cube": "c3", "factor": "f"}


def x_damping() -> str:
    """The stub of damping.py with X's bodies in place of the TODOs."""
    text = (STUBS / "damping.py").read_text()
    for method, body in X_BODIES.items():
        todo = f'        raise NotImplementedError("TODO damping.{method}: not implemented yet")'
        assert todo in text
        text = text.replace(todo, "\n".join("        " + line for line in body.splitlines()))
    return text


def y_damping() -> str:
    """X's file with its local names renamed, comments rewritten and blank lines moved."""
    text = x_damping()
    head, body = text.split("class GavinType1", 1)
    body = body.replace("# scale each diagonal entry", "# multiply diag(H) by lambda, entry by entry")
    body = body.replace("# the slope along h", "\n        # directional derivative g^T h\n")
    for old, new in Y_RENAMES.items():
        body = re.sub(rf"(?<![.\w]){old}(?!\w)", new, body)
    body = body.replace("    return acc\n", "    return acc\n\n")
    return head + "class GavinType1" + body


def malformed_damping() -> str:
    """The reference's damping.py cut off inside a docstring: it does not tokenize."""
    text = (REFERENCE / "damping.py").read_text()
    return text[: text.index('"""Type 3')] + '"""Type 3 (Nielsen), unterminated\n        return 1\n'


#: id -> (name, how the package is made, overall status, {check: (mistake or None, check status)})
CLASS = {
    "s01": ("Ada Lovelace", "solutions", "ok", {}),
    "s02": ("Blaise Pascal", "exercises", "ok", {name: (None, "ok") for name in ALL}),
    "s03": ("Carl Gauss", "type1_lambda_identity", "ok", {T1_DIAG: (LAMBDA_I, "ok"), LM1: (None, "ok")}),
    "s04": ("Dora Markus", "type1_lambda_identity", "ok", {T1_DIAG: (LAMBDA_I, "ok"), LM1: (None, "ok")}),
    "s05": ("Emmy Noether", "residual_sign", "ok", {R_VALUES: (R_SIGN, "ok"), LM1: (None, "ok")}),
    "s06": ("Felix Klein", "step_wrong_sign", "ok", {STEP: (H_SIGN, "ok"), LM1: (None, "ok")}),
    "s07": ("Grace Hopper", "type3_no_nu_reset", "ok", {T3_RESET: (NU_RESET, "ok")}),
    "s08": ("Hedy Lamarr", "exercises", "no files", None),  # an empty tests list
    "s09": ("Ida Rhodes", "infinite_loop", "timed out", {T3_DIAG: (None, "timeout")}),
    "s10": ("Joan Clarke", "malformed", "crashed", {name: (None, "crashed") for name in DAMPING}),
    "s11": ("Kurt Goedel", "x", "ok", {}),
    "s12": ("Bobby <Tables> & Co", "y", "ok", {}),
    "s13": ("Lise Meitner", "exercises", "no files", {name: (None, "not run") for name in ALL}),
}
X, Y = "s11", "s12"


def make_package(how: str, target: Path) -> None:
    """Write the graded package ``target`` as ``how`` says."""
    source = STUBS if how == "exercises" else REFERENCE
    shutil.copytree(source, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "answers"))
    if how in VARIANTS:
        variant = VARIANTS[how]
        path = target / variant.file
        path.write_text(apply(path.read_text(), variant))
    elif how in ("x", "y", "malformed"):
        text = {"x": x_damping, "y": y_damping, "malformed": malformed_damping}[how]()
        (target / "damping.py").write_text(text)


def results(sid: str, name: str, status: str, lost) -> dict:
    """A results.json as the batch writes it."""
    tests = []
    for exercise, check, points in CHECKS if lost is not None else []:
        for hidden in (False, True):
            mistake, check_status = lost.get(check, (None, "ok"))
            failed = check in lost
            extra = {"exercise": exercise, "hidden": hidden, "status": check_status}
            if mistake:
                extra["mistake"] = mistake
            tests.append({"name": check + (HIDDEN if hidden else ""), "score": 0.0 if failed else points,
                          "max_score": points, "output": "Likely cause: " + mistake if mistake else "",
                          "visibility": "after_published" if hidden else "visible", "extra_data": extra})
    score = sum(t["score"] for t in tests)
    return {"score": score, "execution_time": 3.2, "output": f"Total: {score:g}", "tests": tests,
            "extra_data": {"id": sid, "name": name, "status": status, "seconds": 41.2,
                           "graded": "Graded the exercise files in the upload: damping.py, curve_model.py"}}


def write_class(out: Path, roster: dict) -> Path:
    (out / "results").mkdir(parents=True)
    (out / "submissions").mkdir()
    for sid, (name, how, status, lost) in roster.items():
        make_package(how, out / "submissions" / sid)
        (out / "results" / f"{sid}.json").write_text(json.dumps(results(sid, name, status, lost), indent=1))
    (out / "grades.csv").write_text("id,name,score\n")
    return out


@pytest.fixture(scope="module")
def batch_dir(tmp_path_factory):
    return write_class(tmp_path_factory.mktemp("batch") / "out", CLASS)


@pytest.fixture(scope="module")
def report(batch_dir):
    path = write_report(batch_dir, STUBS, REFERENCE)
    return path.read_text()


def test_y_is_a_disguised_copy_of_x():
    x, y = x_damping(), y_damping()
    assert x != y and "lam_zero" in y and "directional derivative" in y
    assert similarity.fingerprint(x).grams == similarity.fingerprint(y).grams  # the normalisation sees through it


@pytest.mark.parametrize("reference", [REFERENCE, None], ids=["with-reference", "without-reference"])
def test_similar_pairs_flags_exactly_the_copy(batch_dir, reference):
    """With the reference, only X-Y. Without it, the reference's code is still discounted here
    because most of the class wrote it (the class-common n-grams), so again only X-Y."""
    found = similarity.compare_class(batch_dir / "submissions", STUBS, reference)
    assert found.reference_used == (reference is not None)
    assert [(p.a, p.b, p.file) for p in found.pairs] == [(X, Y, "damping.py")]
    pair = found.pairs[0]
    assert pair.score == pytest.approx(1.0) and pair.shared >= similarity.MIN_SHARED
    assert pair.lines_a and pair.lines_b
    # every other pair shares too little: at most the same one-line slip (s03 and s04: containment 1)
    others = [f.shared[k] for f in found.files.values() for k in f.scores if (k, f.file) != ((X, Y), "damping.py")]
    assert max(others) < similarity.MIN_SHARED
    # unwritten stubs are never compared; the malformed file is, and is named in a note
    assert "s02" not in found.files["damping.py"].written and "s08" not in found.files["damping.py"].written
    assert any(note.startswith("s10/damping.py does not tokenize") for note in found.notes)


def test_with_the_reference_the_class_common_filter_is_not_needed(batch_dir, monkeypatch):
    """The reference alone discounts what the reference and the mistake students share."""
    monkeypatch.setattr(similarity, "COMMON_FRACTION", 2.0)  # no n-gram is in twice the class
    pairs = similarity.similar_pairs(batch_dir / "submissions", STUBS, REFERENCE)
    assert [(p.a, p.b, p.file) for p in pairs] == [(X, Y, "damping.py")]


def test_the_outlier_bar():
    """A pair must stand out from its file's other pairs: where many pairs are alike (a class
    that shares a common source), a high score alone is not enough."""
    median, mad, bar = similarity.outlier_bar([0.9, 0.1, 0.12, 0.08, 0.11, 0.1])
    assert median == pytest.approx(0.105) and 0.11 < bar < 0.9
    _, _, bar = similarity.outlier_bar([0.75, 0.7, 0.65, 0.72, 0.68, 0.7])
    assert bar > 0.75
    assert similarity.outlier_bar([0.9]) == (0.9, 0.0, 0.0)  # one pair: the absolute rule decides


def test_small_class_needs_the_reference(tmp_path):
    """Two students, the reference and one slip of it: without the reference they are near
    copies of each other and are flagged (nothing tells their shared code from a copy); with
    it, what remains is the slip alone, too little to flag."""
    roster = {sid: CLASS[sid] for sid in ("s01", "s03")}
    out = write_class(tmp_path / "out", roster)
    assert similarity.similar_pairs(out / "submissions", STUBS, REFERENCE) == []
    flagged = {(p.a, p.b) for p in similarity.similar_pairs(out / "submissions", STUBS, None)}
    assert flagged == {("s01", "s03")}


def expected_pass_rate(check: str) -> tuple:
    """(students with full marks, class size) for one check, from the class table."""
    full = sum(1 for _, _, _, lost in CLASS.values() if lost is not None and check not in lost)
    return full, len(CLASS)


def test_report_headline_and_histogram(report):
    assert "13 students" in report
    totals = [sum(points for _, check, points in CHECKS for _ in (0, 1) if lost is not None and check not in lost)
              for _, _, _, lost in CLASS.values()]
    mean = sum(totals) / len(totals)
    assert f"{mean:.1f}" in report and "22 points" in report
    assert re.search(r'<img [^>]*src="data:image/png;base64,[A-Za-z0-9+/=]{200,}"', report)
    assert "<script" not in report.replace("&lt;script", "")  # nothing executable, no external files
    assert "http://" not in report and "https://" not in report


def test_report_pass_rates(report):
    section = report.split('id="checks"')[1].split("</table>")[0]
    rows = re.findall(r"<tr><td>(.*?)</td><td>(.*?)</td><td>(.*?)</td><td>(\d+) / (\d+)</td>", section)
    got = {name: (int(full), int(size)) for name, _, _, full, size in rows}
    for _, check, _ in CHECKS:
        assert got[check] == expected_pass_rate(check)
        assert got[check + HIDDEN] == expected_pass_rate(check)
    shares = [full / size for full, size in got.values()]
    assert shares == sorted(shares)  # hardest first
    assert expected_pass_rate(T1_DIAG) == (7, 13)


def test_report_mistakes(report):
    section = report.split('id="mistakes"')[1].split('id="problems"')[0]
    assert re.search(re.escape(html.escape(LAMBDA_I)) + r"</td><td>2</td><td>[^<]*s03[^<]*s04", section)
    for sentence in (R_SIGN, H_SIGN, NU_RESET):
        assert re.search(re.escape(html.escape(sentence)) + r"</td><td>1</td><td>[^<]*s0", section)


def test_report_problems(report):
    section = report.split('id="problems"')[1].split('id="similar"')[0]
    assert "s09" in section and "timed out" in section and T3_DIAG in section
    assert "s10" in section and "crashed" in section
    assert "s08" in section and "s13" in section and "no files" in section
    assert "s01" not in section and "s11" not in section


def test_report_similarity_is_escaped(report):
    section = report.split('id="similar"')[1]
    assert "s11" in section and "s12" in section and "damping.py" in section
    assert "&lt;/table&gt;&lt;script&gt;" in section and "</table><script>" not in report
    assert "Bobby &lt;Tables&gt; &amp; Co" in report and "<Tables>" not in report
    assert "not a verdict" in section and "reference" in section
    assert "s10/damping.py does not tokenize" in section


def test_report_without_reference_and_command_line(batch_dir, tmp_path):
    out = tmp_path / "copy"
    shutil.copytree(batch_dir, out)
    (out / "results" / "s99.json").write_text("{not json")  # a results file that does not read is named
    proc = subprocess.run([sys.executable, "-m", "autograder.classroom.report", str(out), "--stubs", str(STUBS)],
                          cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == str(out / "report.html")
    text = (out / "report.html").read_text()
    assert "s11" in text.split('id="similar"')[1] and "no reference" in text
    assert "s99.json: not read" in text and "13 students" in text
    assert str(out.resolve()) in text.split('id="footer"')[1]


def test_a_leaked_reference_is_flagged_alone_or_by_several(batch_dir):
    """The pairs discount the reference, so a student handing it in is never a pair; the leak check
    holds each file against the reference's solution blocks: s01 (the reference), s03 and s04 (the
    reference with one slip each, the same one) are flagged; X and Y (their own code) and the stubs
    are not."""
    found = similarity.compare_class(batch_dir / "submissions", STUBS, REFERENCE)
    damping = {leak.student: leak for leak in found.leaks if leak.file == "damping.py"}
    assert {"s01", "s03", "s04"} <= set(damping)
    assert not {X, Y, "s02", "s08", "s13"} & set(damping)
    assert damping["s01"].score == pytest.approx(1.0) and damping["s01"].total >= similarity.LEAK_MIN_GRAMS
    assert similarity.LEAK_CONTAINMENT <= damping["s03"].score < 1.0 and damping["s03"].lines
    assert (X, Y, "damping.py") in {(p.a, p.b, p.file) for p in found.pairs}  # the pairs are unchanged
    assert not any((p.a, p.b) == ("s03", "s04") for p in found.pairs)  # a shared leak is no pair
    # renaming every local name and rewriting the comments hides nothing
    renamed = (REFERENCE / "damping.py").read_text()
    for old, new in (("diag_H", "d"), ("lam", "damping_factor"), ("rho", "gain")):
        renamed = re.sub(rf"(?<![.\w]){old}(?!\w)", new, renamed)
    solution = similarity.solution_grams((REFERENCE / "damping.py").read_text(),
                                         similarity.fingerprint((STUBS / "damping.py").read_text()).grams)
    held = set(similarity.fingerprint(renamed).grams) & solution
    assert len(held) >= similarity.LEAK_CONTAINMENT * len(solution)
    assert similarity.compare_class(batch_dir / "submissions", STUBS, None).leaks == []  # needs the reference


def test_report_lists_the_leaks(report):
    section = report.split('id="leaked"')[1].split('id="footer"')[0]
    rows = re.findall(r"<tr><td>([^<]*)</td><td>([^<]*)</td>", section)
    damping = {who.split(" ")[0] for file, who in rows if file == "damping.py"}
    assert {"s01", "s03", "s04"} <= damping and not {X, Y} & damping
    # X and Y wrote damping.py themselves and copied the reference's other files
    assert any(file == "curve_model.py" and who.startswith(X) for file, who in rows)
