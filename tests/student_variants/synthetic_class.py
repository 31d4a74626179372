"""A synthetic class for ``python -m autograder batch``: one upload folder per student.

The reference, the stubs, each known mistake as its own student (a copy of the reference
with that one slip, :data:`MISTAKES`), a submission whose functions hang, one that
leaves a process behind (forks), one with no exercise file, and two near copies: a
correct damping module written differently from the reference, and the same module
with its names and comments changed.

``python tests/student_variants/synthetic_class.py DIR`` writes the whole class (40
students) to a new DIR; :func:`build` takes a selection of mistakes for a smaller one.
"""

import re
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
if str(HERE.parent) not in sys.path:
    sys.path.insert(0, str(HERE.parent))

from student_variants import BUGS, BUGS_CHAPTERS_2_3, ROOT, apply  # noqa: E402

SOLUTIONS = ROOT / "solutions"
#: the known mistakes of chapters 1 to 3, one student each
MISTAKES = {**BUGS, **BUGS_CHAPTERS_2_3}

#: a correct damping module, written differently from the reference (full marks)
OWN_DAMPING = '''"""Gavin's damping rules, my way."""

import numpy as np

from course.solver.damping import DampingState, DampingStrategy

LOW, HIGH = 1e-7, 1e7


def clamp(value, low=LOW, high=HIGH):
    # keep lambda inside Gavin's bounds
    return float(min(max(value, low), high))


def ones_times(count, value):
    out = np.empty(count)
    out[:] = value
    return out


class GavinType1(DampingStrategy):
    name = "lm-type1"

    def __init__(self, lambda_0=1e-2, l_down=9.0, l_up=11.0):
        self.lambda_0 = lambda_0
        self.l_down = l_down
        self.l_up = l_up

    def initial_state(self, diag_H):
        start = DampingState(lam=self.lambda_0)
        return start

    def damping_diagonal(self, diag_H, lam):
        scaled = np.multiply(diag_H, lam)
        return np.asarray(scaled, dtype=float)

    def gain_denominator(self, h, b, diag_H, lam):
        weighted = np.multiply(np.multiply(diag_H, lam), h)
        return float(np.dot(h, weighted) - np.dot(h, b))

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        # shrink after a good step, grow after a bad one
        factor = 1.0 / self.l_down if accepted else self.l_up
        new_lam = state.lam * factor
        new_lam = max(new_lam, LOW) if accepted else min(new_lam, HIGH)
        return DampingState(lam=new_lam, nu=state.nu)


class GavinType2(DampingStrategy):
    name = "lm-type2"

    def __init__(self, tau=1e-2):
        self.tau = tau

    def initial_state(self, diag_H):
        biggest = float(np.amax(np.asarray(diag_H)))
        return DampingState(lam=biggest * self.tau)

    def damping_diagonal(self, diag_H, lam):
        return ones_times(len(diag_H), lam)

    def step_scale(self, h, b, chi2, chi2_full_step):
        slope = -float(np.dot(b, h))
        denominator = 0.5 * (chi2_full_step - chi2) + 2.0 * slope
        return max(slope / denominator, 0.1)

    def gain_denominator(self, h, b, diag_H, lam):
        return float(np.dot(h, lam * h) - np.dot(h, b))

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        if not accepted:
            grown = state.lam + abs(dchi2) / alpha / 2.0
            return DampingState(lam=grown, nu=state.nu)
        shrunk = state.lam / (alpha + 1.0)
        return DampingState(lam=max(LOW, shrunk), nu=state.nu)


class GavinType3(DampingStrategy):
    name = "lm-type3"

    def __init__(self, tau=1e-2):
        self.tau = tau

    def initial_state(self, diag_H):
        biggest = float(np.amax(np.asarray(diag_H)))
        return DampingState(lam=biggest * self.tau, nu=2.0)

    def damping_diagonal(self, diag_H, lam):
        return ones_times(len(diag_H), lam)

    def gain_denominator(self, h, b, diag_H, lam):
        return float(np.dot(h, lam * h) - np.dot(h, b))

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        if not accepted:
            return DampingState(lam=state.lam * state.nu, nu=state.nu * 2.0)
        cube = (2.0 * rho - 1.0) ** 3
        return DampingState(lam=state.lam * max(1.0 - cube, 1.0 / 3.0), nu=2.0)


STRATEGIES = {cls.name: cls for cls in (GavinType1, GavinType2, GavinType3)}
'''

#: the copy: every name of OWN_DAMPING's own renamed, the comments reworded, a blank line moved
RENAMES = {"clamp": "bound_it", "ones_times": "filled", "start": "first", "scaled": "d_vec", "weighted": "wh",
           "factor": "mult", "new_lam": "lam_next", "biggest": "top", "slope": "gh", "denominator": "den",
           "grown": "bigger", "shrunk": "smaller", "cube": "c3", "LOW": "LAM_MIN", "HIGH": "LAM_MAX"}

REFERENCE_DAMPING = (SOLUTIONS / "damping.py").read_text()
UPDATE = "    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):\n"
assert UPDATE in REFERENCE_DAMPING
#: the reference's damping module, whose update methods never return
HANGING = REFERENCE_DAMPING.replace(UPDATE, UPDATE + "        while True:\n            pass\n")
#: the reference's damping module, leaving a sleeping process behind on every call of initial_state
FORKING = REFERENCE_DAMPING.replace(
    "    def initial_state(self, diag_H):\n",
    "    def initial_state(self, diag_H):\n"
    "        libc = np.ctypeslib.ctypes.CDLL(None)  # no import statement: the grader refuses os\n"
    "        if libc.fork() == 0:\n            libc.sleep(600)\n            libc._exit(0)\n")


def near_copy(source: str) -> str:
    """``source`` with its own names renamed, comments reworded and a blank line added."""
    text = source
    for old, new in RENAMES.items():
        text = re.sub(rf"\b{old}\b", new, text)
    text = text.replace("# keep lambda inside Gavin's bounds", "# clip to the allowed range")
    text = text.replace("# shrink after a good step, grow after a bad one", "# good step: smaller; bad: larger")
    return text.replace("class GavinType2", "\nclass GavinType2")


def _reference(target: Path) -> Path:
    target.mkdir(parents=True)
    for path in SOLUTIONS.glob("*.py"):
        shutil.copyfile(path, target / path.name)
    return target


def _with_damping(target: Path, text: str) -> None:
    _reference(target)
    (target / "damping.py").write_text(text)


def build(root, mistakes=None) -> dict:
    """Write the class into the new folder ``root``; returns ``{student: kind}``. ``mistakes``:
    the names of :data:`MISTAKES` to include (default: every one)."""
    root = Path(root)
    root.mkdir(parents=True)
    kinds = {}
    _reference(root / "reference")
    kinds["reference"] = "reference"
    stubs = root / "stubs" / "my_work"  # inside a folder, as some students upload
    stubs.mkdir(parents=True)
    for path in (ROOT / "exercises").glob("*.py"):
        shutil.copyfile(path, stubs / path.name)
    kinds["stubs"] = "stubs"
    for name in MISTAKES if mistakes is None else mistakes:
        variant = MISTAKES[name]
        target = _reference(root / f"mistake-{name}")
        path = target / variant.file
        path.write_text(apply(path.read_text(), variant))
        kinds[f"mistake-{name}"] = "mistake"
    _with_damping(root / "hangs", HANGING)
    kinds["hangs"] = "hangs"
    _with_damping(root / "forks", FORKING)
    kinds["forks"] = "forks"
    (root / "no-files").mkdir()
    (root / "no-files" / "notes.txt").write_text("I will send it tomorrow\n")
    kinds["no-files"] = "no files"
    _with_damping(root / "copy-a", OWN_DAMPING)
    _with_damping(root / "copy-b", near_copy(OWN_DAMPING))
    kinds["copy-a"] = kinds["copy-b"] = "near copy"
    return kinds


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python tests/student_variants/synthetic_class.py DIR")
    chosen = sorted(MISTAKES)[:33]  # 33 mistakes + 7 others = 40 students
    print(f"{len(build(sys.argv[1], chosen))} students in {sys.argv[1]}")
