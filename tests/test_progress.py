"""Long runs show which back end and method runs, with our iteration and chi2, on a
terminal only."""

import io

from conftest import needs

from course.app import compare
from course.core.progress import Progress
from course.problems.posegraph import dataset as datasets


class _Terminal(io.StringIO):
    def isatty(self):
        return True


@needs("pyceres", "g2opy", "gtsam")
def test_a_comparison_reports_each_run_and_our_iterations_on_a_terminal():
    screen = _Terminal()
    progress = Progress(2, label="w100", file=screen)
    runs = compare.run_posegraph(datasets.load_dataset("w100"), impl="solutions", methods=["gauss-newton"],
                                 backends=["ours", "g2o"], progress=progress)
    progress.close()
    shown = screen.getvalue()
    assert len(runs) == 2
    assert f"ours gauss-newton: iteration {runs[0].iterations}, chi2 " in shown
    assert "1/2 runs" in shown and "g2o gauss-newton" in shown


def test_quiet_when_not_a_terminal():
    pipe = io.StringIO()
    progress = Progress(1, label="curve", file=pipe)
    compare.run_curve(impl="solutions", methods=["gauss-newton"], backends=["ours"], progress=progress)
    progress.close()
    assert pipe.getvalue() == ""


@needs("g2opy", "gtsam")
def test_the_benchmark_reports_each_repeat():
    from course.app import benchmark

    screen = _Terminal()
    progress = Progress(2, label="w100", file=screen)
    ours, theirs, *_ = benchmark.gauss_newton_vs_g2o("w100", repeats=1, progress=progress)
    progress.close()
    assert ours > 0 and theirs > 0
    assert "ours gauss-newton: iteration" in screen.getvalue() and "g2o gauss-newton" in screen.getvalue()
