"""autograder.release.input_reach: the checks' inputs reach the reference's graded branches."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import needs

from autograder.release.input_reach import error_lines, graded_lines

ROOT = Path(__file__).resolve().parent.parent
#: the share of the graded statements and branches (between the solution markers) some input reaches
LEAST = 0.95


def test_graded_lines_are_strictly_between_the_markers(tmp_path):
    path = tmp_path / "one.py"
    path.write_text("def f(x):\n    # BEGIN SOLUTION\n    y = x\n    return y\n    # END SOLUTION\n\n\n"
                    "def g():\n        # BEGIN SOLUTION\n        pass\n        # END SOLUTION\n")
    assert graded_lines(path) == {3, 4, 10}


def test_error_lines_are_raises_and_except_clauses(tmp_path):
    path = tmp_path / "one.py"
    path.write_text("try:\n    x = 1\nexcept ValueError:\n    y = 2\n    raise RuntimeError(\n        'no')\n"
                    "if x:\n    raise ValueError('x')\nz = 3\n")
    assert error_lines(path) == {3, 4, 5, 6, 8}


@pytest.mark.slow
@needs("pyceres", "qdldl")
def test_the_checks_inputs_reach_the_graded_branches():
    # a fresh process: the oracle remembers outputs, and a call it does not run again is not measured
    done = subprocess.run([sys.executable, "-m", "autograder.release.input_reach", "--json"], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    reach = json.loads(done.stdout)
    left = "\n".join(reach["missed"])
    print(f"graded: {100 * reach['graded']:.1f}%, whole files: {100 * reach['whole']:.1f}%; not reached:\n{left}")
    assert reach["graded"] >= LEAST, (
        f"the checks' public and hidden inputs reach {100 * reach['graded']:.1f}% of the graded statements and "
        f"branches of solutions/ (at least {100 * LEAST:.0f}% wanted); give these an input:\n{left}"
    )
    # what is left today is error paths alone (an input the reference refuses is not a graded call yet)
    assert not reach["missed_others"], "no check's input reaches these:\n" + "\n".join(reach["missed_others"])
