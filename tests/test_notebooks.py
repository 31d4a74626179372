"""The generated notebooks: current with their py:percent sources (notebooks/chapter*.py), and they run.

Chapters 2, 3, 3b, 4 and 5 run in their small setting (``COURSE_NOTEBOOK_SMALL=1``: w100,
``manhattan:N``, the curve, ``bal-synthetic:C:P`` and ``vio-sim:4:0``; seconds each); their
full setting is ``python -m notebooks.build --execute`` (``make notebooks``).

Execution uses ``notebooks.build.execute``, which starts the kernel on this test's own
interpreter (``sys.executable``): the ``python3`` kernelspec when it resolves to it,
else a kernelspec written to a temporary ``JUPYTER_PATH`` folder.
"""

import sys
from pathlib import Path

import nbformat
import pytest
from conftest import needs
from executed_notebooks import executed_small

from notebooks import build


def _sources(nb):
    return [(cell.cell_type, cell.get("id"), cell.source) for cell in nb.cells]


@pytest.mark.parametrize("path", list(build.NOTEBOOKS), ids=lambda p: p.name)
def test_committed_notebook_is_current(path):
    assert path.is_file(), f"{path.name} missing: run `python -m notebooks.build`"
    committed = nbformat.read(path, as_version=4)
    nbformat.validate(committed)
    assert _sources(committed) == _sources(build.read(build.NOTEBOOKS[path])), (
        f"{path.name} is stale: run `python -m notebooks.build --execute`"
    )


@pytest.mark.parametrize("path", list(build.NOTEBOOKS), ids=lambda p: p.name)
def test_source_round_trips_with_ids_and_tags(path, tmp_path):
    """Each source is jupytext py:percent, one ``id="..."`` per cell; ``writes`` gives it back."""
    source = build.NOTEBOOKS[path]
    assert source == path.with_suffix(".py") and source.is_file()
    nb = build.read(source)
    ids = [cell.id for cell in nb.cells]
    assert len(set(ids)) == len(ids)
    assert build.writes(nb) == source.read_text()
    copy = tmp_path / source.name
    copy.write_text(build.writes(nb))
    again = build.read(copy)
    assert [(c.id, c.source, c.metadata) for c in again.cells] == [(c.id, c.source, c.metadata) for c in nb.cells]
    tagged = {cell.id for cell in nb.cells if build.ANSWER_TAG in cell.metadata.get("tags", [])}
    expected = {"answer-1", "answer-2"} if path == build.CHAPTER4 else set()
    if path == build.CHAPTER1:
        expected = {"answer-1", "answer-2", "answer-3"}
    if path in (build.CHAPTER3, build.CHAPTER3B):  # their lessons' four questions
        expected = {f"answer-{k}" for k in range(1, 5)}
    if path == build.CHAPTER5:  # its lesson's four questions
        expected = {f"answer-{k}" for k in range(1, 5)}
    if path in (build.CHAPTER2, build.CHAPTER6):  # their lessons' five questions
        expected = {f"answer-{k}" for k in range(1, 6)}
    if path == build.CHAPTER4:  # its lesson's five questions
        expected = {f"answer-{k}" for k in range(1, 6)}
    if path in (build.CHAPTER7, build.CHAPTER8):  # their lessons' six questions
        expected = {f"answer-{k}" for k in range(1, 7)}
    assert tagged == expected
    assert all(set(cell.metadata) <= {"tags"} for cell in nb.cells)


def test_a_cell_without_an_id_is_refused(tmp_path):
    source = tmp_path / "nb.py"
    source.write_text('# %% [markdown] id="title"\n# # Title\n\n# %%\nprint(1)\n')
    with pytest.raises(ValueError, match="without id"):
        build.read(source)


def test_rebuilding_keeps_an_edited_answer_and_the_committed_answers(tmp_path):
    """An answer written in the .ipynb survives a rebuild from the source; other cells follow the source."""
    (path,) = build.build(out_dir=tmp_path, only=["chapter2"])
    nb = nbformat.read(path, as_version=4)
    cells = {c.id: c for c in nb.cells}
    cells["answer-2"].source = "**Your answer to question 2:** trust-region methods."
    cells["setup"].source = "# edited by hand"
    nbformat.write(nb, path)
    build.build(out_dir=tmp_path, only=["chapter2"])
    rebuilt = {c.id: c for c in nbformat.read(path, as_version=4).cells}
    assert rebuilt["answer-2"].source.endswith("trust-region methods.")
    assert build.ANSWER_TAG in rebuilt["answer-2"].metadata["tags"]
    assert rebuilt["setup"].source == {c.id: c for c in build.read(build.NOTEBOOKS[build.CHAPTER2]).cells}[
        "setup"].source


def test_progress_lines_name_the_notebook_and_cell(capsys):
    from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

    nb = new_notebook(cells=[new_markdown_cell("# t"), new_code_cell("x = 1"), new_code_cell("y = 2")])
    nb.cells[2]["id"] = "second"
    report = build._Progress("demo.ipynb", nb)
    for index, cell in enumerate(nb.cells):
        report.on_cell_start(cell=cell, cell_index=index)
    report.close()
    lines = capsys.readouterr().err.splitlines()
    if report.bar is None:
        assert lines[-1] == "demo.ipynb: cell 2/2 (second)" and len(lines) == 2


def _kernel_executable():
    """sys.executable as seen by a kernel started by ``build.execute``."""
    from nbformat.v4 import new_code_cell, new_notebook

    nb = new_notebook(cells=[new_code_cell("import sys; print(sys.executable, end='')")])
    build.execute(nb, timeout=120)
    return nb.cells[0].outputs[0]["text"]


def test_kernel_runs_this_interpreter():
    assert _kernel_executable() == sys.executable


def test_the_killed_kernel_leaves_no_grading_runtime():
    """The kernel is killed after the last cell (no exit handlers): the runtime a check cell staged goes first."""
    from nbformat.v4 import new_code_cell, new_notebook

    from autograder import isolation

    if not isolation.is_root():
        pytest.skip("a runtime is staged in a folder of its own only when isolating the children (root)")
    nb = new_notebook(cells=[new_code_cell("from autograder import runtime, sandbox\n"
                                           "print(runtime.acquire(True, sandbox.REPO_ROOT).base, end='')")])
    build.execute(nb, timeout=120)
    staged = Path(nb.cells[0].outputs[0]["text"])
    assert staged.name.startswith("autograder-runtime-") and not staged.exists()


def test_kernel_falls_back_to_a_temporary_kernelspec(monkeypatch):
    """When the ``python3`` spec names another interpreter, a temporary spec is used."""
    import os

    from jupyter_client.kernelspec import KernelSpecManager

    original = KernelSpecManager.get_kernel_spec

    def fake(self, name):
        spec = original(self, name)
        if name == "python3":
            spec.argv = ["/some/other/python3.9", *spec.argv[1:]]
        return spec

    monkeypatch.setattr(KernelSpecManager, "get_kernel_spec", fake)
    before = os.environ.get("JUPYTER_PATH")
    with build.kernel_for_this_interpreter() as name:
        assert name == "course-python"
    assert os.environ.get("JUPYTER_PATH") == before
    assert _kernel_executable() == sys.executable


@pytest.mark.slow
def test_chapter1_executes(tmp_path):
    nb = executed_small(build.CHAPTER1)
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    text = "\n".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs if o.output_type == "stream"
    )
    for word in ("lm-type1", "lm-type2", "lm-type3", "levenberg-marquardt", "scipy", "source iters",
                 "largest relative difference", "chi2 at (0, 0, 0): 36048.3", "iter: 3 , chi= 7273.96",
                 "every chi2 the C++ run prints is ours: True", "no cap"):
        assert word in text
    # the check cells grade through the autograder: the notebook's implementation has full marks
    results = "\n".join(o["data"].get("text/plain", "") for c in nb.cells if c.cell_type == "code"
                        for o in c.outputs if o.output_type == "execute_result")
    for exercise in ("curve_model", "gauss_newton", "damping"):
        assert f"{exercise} (solutions): " in results and f"{exercise}." in text
    assert results.count("full marks on the public checks") == 3, results
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]
    assert len(images) == 6  # the model and the rules (theory), lambda, chi2, the fit, the source's data
    # same numbers as in-process
    from course.app import compare
    from course.problems.curve.problem import generate

    ours = compare.run_curve(data=generate(), backends=["ours"], methods=["lm-type1"])[0]
    assert f"{ours.final_chi2:.6f}" in text
    nbformat.write(nb, tmp_path / "executed.ipynb")


def _execute_small(path):
    """Run notebook ``path`` (built from its source) in the small setting; returns (text of its outputs, images)."""
    nb = executed_small(path)
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, errors
    text = "\n".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    text += "\n".join(o["data"]["text/markdown"] for o in outputs if "text/markdown" in o.get("data", {}))
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    return nb, text, images


@needs("gtsam")
@pytest.mark.slow
def test_chapter2_executes_small():
    nb, text, images = _execute_small(build.CHAPTER2)
    for words in ("dense/sparse", "growth exponents", "w100: 100 poses, 300 edges",
                  "manhattan:200: 200 poses", "errors and Jacobians", "factorization and solve",
                  "measured in the loop", "Converged (stopped by their own test"):
        assert words in text
    assert "w10000" not in text  # the full setting only
    assert len(images) == 6  # the theory's four (tests/test_lesson_2.py), before/after, dense and sparse against N
    # the written questions are asked, with an empty answer cell each, and not answered
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    assert "Question 1" in markdown["questions-md"] and "Question 2" in markdown["questions-md"]
    assert "Your answer to question 1" in markdown["answer-1"]
    assert "Your answer to question 2" in markdown["answer-2"]
    # same numbers as in-process
    from course.app import compare
    from course.problems.posegraph import dataset as datasets

    ours = compare.run_posegraph(datasets.load_dataset("w100"), methods=["gauss-newton"], backends=["ours"])[0]
    assert f"{ours.final_chi2:.10g}" in text


@pytest.mark.slow
def test_chapter3_executes_small():
    import re

    _, text, images = _execute_small(build.CHAPTER3)
    for words in ("curve (start chi2", "manhattan:200 (start chi2", "at GN minimum", "factorizations / step attempts"):
        assert words in text
    assert len(images) == 6  # the path and the radius (theory); per iteration and per second, curve and manhattan:200
    # after every rejection the dogleg retries without a factorization; LM type 1 factorizes again
    assert re.search(r"dogleg: [1-9]\d* retries after a rejection, new factorizations before each: \[0\]", text)
    assert re.search(r"lm-type1: [1-9]\d* retries after a rejection, new factorizations before each: \[1\]", text)


@pytest.mark.slow
def test_chapter3b_executes_small():
    import time

    start = time.perf_counter()
    nb, text, images = _execute_small(build.CHAPTER3B)
    assert time.perf_counter() - start < 60, "the quick setting should take seconds"
    assert "Traceback" not in text
    for words in ("manhattan:300:0 from file", "manhattan:300:0 from chordal", "start chi2", "init ms",
                  "final chi2", "lowest", "gauss-newton", "lm-type3", "dogleg", "lowest final chi2: manhattan:200",
                  "manhattan:1000: 1000 poses", "time to solution", "total ms"):
        assert words in text, words
    for init in ("file", "tree", "chordal"):
        assert f"manhattan:200 {init}" in text
    for name in ("intel", "m3500", "w10000"):  # the full setting only
        assert name not in text
    assert len(images) == 4  # the drift, the tree, the relaxation (theory); the basin: two starts, two panels each
    # a peer not installed here is a row saying so, else a row of numbers
    for backend in ("g2o", "gtsam"):
        assert f"{backend:8} gauss-newton  file" in text
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    assert "Question 1" in markdown["questions-md"] and "Question 2" in markdown["questions-md"]
    assert "Your answer to question 1" in markdown["answer-1"]
    assert "Your answer to question 2" in markdown["answer-2"]
    # same numbers as in-process
    from course.app import compare
    from course.problems.posegraph import dataset as datasets

    ours = compare.run_posegraph(datasets.load_dataset("manhattan:300"), methods=["gauss-newton"],
                                 backends=["ours"], init="chordal")[0]
    assert f"-> {ours.final_chi2:.6g} in {ours.iterations} iterations" in text


@pytest.mark.slow
def test_chapter4_executes_small():
    import time

    from course.core import peers

    start = time.perf_counter()
    nb, text, images = _execute_small(build.CHAPTER4)
    assert time.perf_counter() - start < 60, "the quick setting should take seconds"
    assert "Traceback" not in text
    for words in ("bal-synthetic:6:40:0: 6 cameras, 40 points", "neighbours 1", "nonzeros", "density",
                  "bal-synthetic:10:300:0: 10 cameras, 300 points, 1036 observations, at most 20 iterations",
                  "final cost (ours)", "peer final cost", "behind camera start->final",
                  "milliseconds per iteration", "(4 points mirrored)", "observations have their point behind",
                  "one damped step, 10 cameras", "growth exponent", "no outliers, least squares", "cauchy(a=2.45)",
                  "tukey(a=4.5)", "the source's table", "218.77", "148.73", "61.42", "83.40",
                  "Parallel assembly of the normal equations", "gauge free : 7 of", "gauge fixed: 0 of",
                  "gauge_directions N", "ours / ceres", "bal-synthetic:20:900:0"):
        assert words in text, words
    for words in ("ladybug-49: milliseconds per iteration", "bal-synthetic:30:3000", "cost @ 1000",
                  "bal-synthetic:400:86000"):
        assert words not in text, words  # the full setting only
    if peers.installed("gtsam"):  # dubrovnik-3-7 ships with gtsam
        for words in ("38 residuals (2 per observation) for 48 unknowns", "null space 3", "cost @ 100", "f_2"):
            assert words in text, words
    # the theory's camera, Taylor test, sparsity, kernels, IRLS and gauge; costs on the synthetic problem, the
    # size sweep, dense against Schur
    assert len(images) == 9
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    assert "Question 1" in markdown["questions-md"] and "Question 2" in markdown["questions-md"]
    assert "Your answer to question 1" in markdown["answer-1"]
    assert "Your answer to question 2" in markdown["answer-2"]
    # same numbers as in-process
    from course.app import compare
    from course.problems.bal.dataset import load_bal

    ours = compare.run_bal(load_bal("bal-synthetic:10:300"), methods=["lm-type3"], backends=["ours"],
                           max_iterations=20)[0]
    assert f"{ours.final_chi2:.10g}" in text


@pytest.mark.slow
def test_chapter5_executes_small():
    import time

    from course.core import peers
    from course.core.errors import DatasetError

    start = time.perf_counter()
    nb, text, images = _execute_small(build.CHAPTER5)
    assert time.perf_counter() - start < 90, "the quick setting should take well under a minute"
    assert "Traceback" not in text and "did not run here" not in text and "not implemented" not in text
    for words in ("vio-sim:4:0: 801 IMU samples of ground truth", "window 10 (with prior)", "window 10 (without prior)",
                  "17 keyframes", "before: n = ", "(10 frames, ", "removed: the oldest frame and ", "fill-in ",
                  "the block that fills in: ", "after: the next window at its start", "diag(H) of the next window",
                  "solves with a prior, from t = 2.50 s", "dof - rank: ", "APE rmse (m)", "s/solve", "batch  "):
        assert words in text, words
    assert "vio-sim:12:0" not in text  # the full setting only
    if peers.installed("gtsam"):
        for words in ("GTSAM batch", "GTSAM fixed-lag (window 10)"):
            assert words in text, words
    else:
        assert "GTSAM: not run (gtsam is not installed here" in text
    try:
        from course.problems.vio.ape import euroc_mh05_files

        euroc_mh05_files()
    except DatasetError:
        assert "EuRoC MH_05: skipped" in text
    else:  # the source's evaluation: ours equals evo's, beside the source's LM row
        for words in ("ours                    0.245723  0.231451", "source's LM run         0.247000", "rmse within"):
            assert words in text, words
    # the lesson's preintegration, window graph and marginal figures; fill-in, cost and prior size, APE over time
    assert len(images) == 6
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    assert "Question 1" in markdown["questions-md"] and "Question 2" in markdown["questions-md"]
    assert "Your answer to question 1" in markdown["answer-1"]
    assert "Your answer to question 2" in markdown["answer-2"]
    # same numbers as in-process
    from course.problems.vio.ape import ape
    from course.problems.vio.sim import load_vio_sim
    from course.problems.vio.window import ground_truth, sliding_window

    sim = load_vio_sim("vio-sim:4:0")
    drop = sliding_window(sim, "drop")
    assert f"{drop.label:<30} {ape(ground_truth(sim), drop.trajectory()).stats['rmse']:>12.4f}" in text


def test_reference_answers_stay_out_of_the_student_tree():
    from autograder.release import stubs as release
    from course.core.impl import REPO_ROOT

    answers = REPO_ROOT / "solutions" / "answers"
    for chapter in ("chapter1", "chapter2", "chapter3", "chapter3b", "chapter4", "chapter5", "chapter6", "chapter7",
                    "chapter8"):
        assert (answers / f"{chapter}.md").is_file(), chapter
    files = release.render(REPO_ROOT / "solutions")
    assert not [name for name in files if name.startswith("answers")]


@pytest.mark.slow
def test_chapter6_executes_small(data_folder):
    import time

    start = time.perf_counter()
    nb, text, images = _execute_small(build.CHAPTER6)
    assert time.perf_counter() - start < 90, "the quick setting should take well under a minute"
    assert "Traceback" not in text and "not implemented" not in text
    for words in ("smallGrid3D from file: 125 poses, 297 edges", "smallGrid3D from chordal", "462.4825302",
                  "start: chordal initialisation", "chordal start  median", "errors against our solution without "
                  "outliers", "ours GNC TLS", "ours cauchy", "20% ours least squares"):
        assert words in text, words
    assert "sphere2500" not in text and "torus3D" not in text  # the full setting only
    # the theory's five (perturbations, right Jacobian, sparsity, chordal, surrogates), the trajectories
    # and the spectrum of smallGrid3D, GNC's weights round by round
    assert len(images) == 8
    markdown = {c.get("id"): c.source for c in nb.cells if c.cell_type == "markdown"}
    assert "Question 1" in markdown["questions-md"] and "Your answer to question 2" in markdown["answer-2"]
