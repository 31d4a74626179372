"""Build the course notebooks from their py:percent sources, and optionally execute them.

    python -m notebooks.build              # write notebooks/*.ipynb, no outputs
    python -m notebooks.build --execute    # write and run them (outputs saved in the file)
    python -m notebooks.build --small      # with --execute: one run per timing, not five,
                                           # chapters 2, 3 and 3b on small graphs only,
                                           # chapter 4 on synthetic problems, chapter 5 on a
                                           # 4-second simulation, chapter 7 on intel alone
    python -m notebooks.build --only chapter2 chapter3   # only those notebooks
    python -m notebooks.build --execute --out /tmp/nb    # write them elsewhere

Chapter 1 is a lesson (the theory derived, a ``check("...")`` cell after each exercise's theory,
the experiments: damping strategies on the curve and the C++ source's run on its own data, then
written questions), chapter 2 pose graphs (dense against
sparse, every back end on every named dataset, the written questions), chapter 3 the
dogleg against Levenberg-Marquardt, chapter 3b the starts (file, spanning tree, chordal)
and the time to solution, chapter 4 bundle adjustment (the sparsity of J, H and S, ours
against the peers on ladybug-49, rank deficiency, points behind the camera, dense against
Schur, robust kernels, the parallel assembly, the gauge), chapter 5 a sliding-window
visual-inertial back end (the fill-in of H when a keyframe is marginalised, the window's
cost and the prior's size, the APE over time of the window with and without the prior,
the batch and GTSAM's, the source's EuRoC MH_05 table), chapter 6 3D pose graphs (every back
end from the file's poses and the chordal start, the trajectories, the spectrum of rotation
errors, wrong loop closures against least squares, a Cauchy kernel and GNC), chapter 7 a lesson
on the factor graph with automatic differentiation (dual numbers and Jets, finite differences
against Jets by the step size, the chain rule through a retraction, the generic block-sparse
linearisation; then intel, sphere2500 and ladybug-49 as factor graphs: automatic against analytic
Jacobians, the same minimum, the benchmark, a GPS factor in five lines, and range-only SLAM from the
factor library against GTSAM's own factors), chapter 8 a lesson on elimination (one variable eliminated
by QR or by completing the square, the Bayes net and back-substitution, the elimination game and a
minimum-degree ordering against AMD on intel, every pose's marginal covariance by the recursion on R).

Each notebook's source is a jupytext py:percent file next to it (``chapter2_pose_graphs.py``
for ``chapter2_pose_graphs.ipynb``); edit the source, then rebuild. A cell starts with
``# %%`` (code) or ``# %% [markdown]``, followed by its metadata: ``id="..."`` (the cell id,
fixed so that rebuilding gives the same file and ``tests/test_notebooks.py`` can check
that the committed notebook's cells are current) and ``tags=["answer"]``. The cells hold
no logic of their own: they call the package (``course.app.compare``, ``course.app.plot``,
``course.notebook_helpers.common``, ...). They read their settings from the environment
(``COURSE_IMPL``, ``COURSE_NOTEBOOK_REPEAT``, ``COURSE_NOTEBOOK_SMALL``), so they are the
same whatever the build options. Without ``COURSE_IMPL`` they use the tree's own
implementation: ``solutions`` in the course's repository, ``exercises`` in a student tree.

Answer cells (the written questions' cells, tagged ``answer``) belong to whoever writes in
them: when the target ``.ipynb`` exists, rebuilding keeps the source of each of its
answer cells, matched by cell id.

Progress goes to stderr: one line per notebook (written, its run time, the cells that stopped at
an unwritten TODO or failed), a tqdm bar over its cells when stderr is a terminal, and with
``--verbose`` one line per cell elsewhere. A failing cell does not stop the build: its output is
its error (one short line for an unwritten TODO, ``not written yet: TODO module.function``, and
for each later cell that needs what it did not compute), the next cells and notebooks run, and the
exit status is 0 unless a cell failed for another reason than a TODO.

Kernel: ``execute`` runs the kernel on *this* interpreter (``sys.executable``), so the
notebook sees the same packages as the caller. It uses the ``python3`` kernelspec when
that resolves to this interpreter (jupyter_client replaces a bare ``python``/``python3``
in the spec's argv with ``sys.executable``; an absolute path must equal it, compared
without resolving symlinks: a venv's python links to the base interpreter); otherwise it
writes a kernelspec for this interpreter into a temporary folder put first on
``JUPYTER_PATH`` for the run.
"""

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import nbformat

from course.core import peers

HERE = Path(__file__).resolve().parent
CHAPTER1 = HERE / "chapter1_curve_fitting.ipynb"
CHAPTER2 = HERE / "chapter2_pose_graphs.ipynb"
CHAPTER3 = HERE / "chapter3_dogleg.ipynb"
CHAPTER3B = HERE / "chapter3b_initialisation.ipynb"
CHAPTER4 = HERE / "chapter4_bundle_adjustment.ipynb"
CHAPTER5 = HERE / "chapter5_vio.ipynb"
CHAPTER6 = HERE / "chapter6_pose_graphs_3d.ipynb"
CHAPTER7 = HERE / "chapter7_factor_graphs.ipynb"
CHAPTER8 = HERE / "chapter8_elimination.ipynb"

#: each notebook and its py:percent source
NOTEBOOKS = {path: path.with_suffix(".py")
             for path in (CHAPTER1, CHAPTER2, CHAPTER3, CHAPTER3B, CHAPTER4, CHAPTER5, CHAPTER6, CHAPTER7,
                          CHAPTER8)
             if path.is_file() or path.with_suffix(".py").is_file()}  # an assignment tree ships its chapters only


#: the tag of the cells a reader writes in (kept by ``build`` when the notebook is rebuilt)
ANSWER_TAG = "answer"

#: the py:percent format; cell metadata other than ``id`` and ``tags`` is not written
FORMAT = "py:percent"


def read(source) -> nbformat.NotebookNode:
    """The notebook of the py:percent file ``source``, without outputs: each cell's
    ``id="..."`` metadata becomes its cell id; the kernelspec is ``python3``."""
    import jupytext  # not at the top: without it (no wheel for every Python) ``shipped`` stands in

    nb = jupytext.read(source, fmt=FORMAT)
    for cell in nb.cells:
        cell_id = cell.metadata.pop("id", None)
        if cell_id is None:
            raise ValueError(f"{source}: a cell without id=\"...\": {cell.source[:60]!r}")
        cell["id"] = cell_id
        for key in set(cell.metadata) - {"tags"}:  # jupytext's own (lines_to_next_cell, ...)
            del cell.metadata[key]
    nb.metadata = nbformat.from_dict({
        "kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"},
        "language_info": {"name": "python"},
    })
    nb.nbformat, nb.nbformat_minor = 4, 5
    nbformat.validate(nb)
    return nb


def writes(nb) -> str:
    """``nb`` as py:percent text (cell ids as ``id="..."``, tags kept), the inverse of ``read``."""
    nb = nbformat.from_dict(nb)
    for cell in nb.cells:
        cell.metadata["id"] = cell["id"]
        cell.pop("outputs", None)
    nb.metadata = nbformat.from_dict({
        "jupytext": {"notebook_metadata_filter": "-all", "cell_metadata_filter": "id,tags,-all"}})
    import jupytext

    return jupytext.writes(nb, fmt=FORMAT)


def shipped(path) -> nbformat.NotebookNode:
    """The ``.ipynb`` at ``path`` as shipped, without outputs: the notebook where jupytext
    is not installed to read its source (the two are kept in sync by the release)."""
    nb = nbformat.read(path, as_version=4)
    for cell in nb.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    return nb


def default_impl() -> str:
    """This tree's own implementation: ``solutions`` when the reference package is next to
    ``notebooks/`` (the course's repository), else ``exercises`` (a student tree)."""
    return "solutions" if (HERE.parent / "solutions" / "__init__.py").is_file() else "exercises"


def keep_answers(nb, existing) -> int:
    """Copy into ``nb``'s answer cells the source of the same cells (by id) in the notebook
    file ``existing``, when it exists; returns how many answer cells were kept."""
    existing = Path(existing)
    if not existing.is_file():
        return 0
    written = {cell.get("id"): cell.source for cell in nbformat.read(existing, as_version=4).cells}
    kept = 0
    for cell in nb.cells:
        if ANSWER_TAG in cell.get("metadata", {}).get("tags", []) and cell.get("id") in written:
            cell.source = written[cell.get("id")]
            kept += 1
    return kept


#: run silently in the kernel before the first cell: an exception in a cell shows as one short output,
#: ``not written yet: TODO module.function (...)`` for an unwritten exercise, and ``not run: ...`` for a
#: cell that fails after such a cell (it needs what that cell did not compute); any other error as usual
SHORT_ERRORS = r"""
def _course_short_errors():
    import re

    from IPython import get_ipython

    stopped = []

    def handler(self, etype, value, tb, tb_offset=None):  # shows the error itself, as IPython expects
        text = str(value)
        todo = re.search(r"TODO [\w.]+", text)
        if issubclass(etype, NotImplementedError) and todo:
            stopped.append(todo.group(0))
            module = todo.group(0)[5:].split(".")[0]
            stb = [f"not written yet: {todo.group(0)} (your {module}.py; "
                   f"`python -m autograder --only {module}` grades it)"]
        elif stopped:
            stb = [f"not run: this cell needs what a cell above did not compute ({stopped[-1]}) "
                   f"[{etype.__name__}: {text[:160]}]"]
        else:
            self.showtraceback((etype, value, tb), tb_offset=tb_offset)
            return None
        self._showtraceback(etype, value, stb)
        return stb

    get_ipython().set_custom_exc((Exception,), handler)


_course_short_errors()
del _course_short_errors
"""

#: run silently in the kernel after the last cell: the kernel is then killed, which runs no exit handlers, so
#: the grading runtime a check cell staged (``autograder.runtime``) is removed first
CLOSE_RUNTIMES = r"""
import sys as _sys
if "autograder.runtime" in _sys.modules:
    _sys.modules["autograder.runtime"].close_all()
del _sys
"""

#: how ``SHORT_ERRORS`` starts the outputs it shortens
TODO_MARK, AFTER_TODO_MARK = "not written yet: TODO ", "not run: this cell needs what a cell above"


def failures(nb) -> dict:
    """The failed cells of an executed notebook: ``{"todo": [...], "after_todo": [...], "error": [...]}``,
    each a list of ``(cell id, first line of its error)``; ``todo`` the cells that stopped at an
    unwritten exercise, ``after_todo`` the cells that failed after one (they need its results),
    ``error`` any other failure."""
    found: dict = {"todo": [], "after_todo": [], "error": []}
    for cell in nb.cells:
        if cell.cell_type != "code":
            continue
        for output in cell.get("outputs", []):
            if output.get("output_type") != "error":
                continue
            first = (output.get("traceback") or [f"{output.get('ename')}: {output.get('evalue')}"])[0]
            kind = "todo" if first.startswith(TODO_MARK) else "after_todo" if first.startswith(AFTER_TODO_MARK) \
                else "error"
            line = first if kind != "error" else f"{output.get('ename')}: {output.get('evalue')}"
            found[kind].append((cell.get("id", ""), line.splitlines()[0] if line else ""))
    return found


def todo_name(line: str) -> str:
    """``module.function`` from a ``not written yet: TODO module.function (...)`` line."""
    return line[len(TODO_MARK):].split(" ")[0]


def outcome(name, nb, seconds=None) -> str:
    """One line for an executed notebook: written, and which cells stopped at a TODO or failed."""
    found = failures(nb)
    code = sum(c.cell_type == "code" for c in nb.cells)
    took = f" in {seconds:.0f} s" if seconds is not None else ""
    if not any(found.values()):
        return f"{name}: all {code} code cells ran{took}"
    parts = []
    if found["todo"]:
        todos = list(dict.fromkeys(todo_name(line) for _, line in found["todo"]))
        parts.append(f"{len(found['todo'])} cell(s) stopped at a TODO ({', '.join(todos)})")
    if found["after_todo"]:
        parts.append(f"{len(found['after_todo'])} after them need their results")
    if found["error"]:
        cell, line = found["error"][0]
        parts.append(f"{len(found['error'])} failed (first: cell {cell}: {line})")
    ok = code - sum(len(v) for v in found.values())
    return f"{name}: {ok} of {code} code cells ran{took}; " + "; ".join(parts)


class _Progress:
    """Reports each executed cell on stderr: a tqdm bar on a terminal; elsewhere one line per cell
    when ``verbose``, else nothing (the build's one line per notebook says how it went)."""

    def __init__(self, name, nb, verbose=True):
        self.name = name
        self.code = [i for i, cell in enumerate(nb.cells) if cell.cell_type == "code"]
        self.bar = None
        self.verbose = verbose
        if sys.stderr.isatty():
            from tqdm import tqdm

            self.bar = tqdm(total=len(self.code), desc=name, unit="cell", file=sys.stderr)

    def on_cell_start(self, cell, cell_index, **_):
        if cell_index not in self.code:  # nbclient starts markdown cells too
            return
        k = self.code.index(cell_index) + 1
        if self.bar is not None:
            self.bar.set_postfix_str(cell.get("id", ""))
            self.bar.update(k - 1 - self.bar.n)
        elif self.verbose:
            print(f"{self.name}: cell {k}/{len(self.code)} ({cell.get('id', '')})", file=sys.stderr, flush=True)

    def close(self):
        if self.bar is not None:
            self.bar.update(self.bar.total - self.bar.n)
            self.bar.close()


@contextlib.contextmanager
def kernel_for_this_interpreter():
    """Yield a kernel name whose kernel runs on ``sys.executable`` (see the module docstring)."""
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    bare = {"python", f"python{sys.version_info[0]}", "python{}.{}".format(*sys.version_info[:2])}
    try:
        argv0 = KernelSpecManager().get_kernel_spec("python3").argv[0]
    except NoSuchKernel:
        argv0 = None
    if argv0 is not None and (argv0 in bare or os.path.abspath(argv0) == os.path.abspath(sys.executable)):
        yield "python3"
        return
    import json

    with tempfile.TemporaryDirectory(prefix="course-kernel-") as tmp:
        spec_dir = Path(tmp) / "kernels" / "course-python"
        spec_dir.mkdir(parents=True)
        spec = {
            "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
            "display_name": "course (this interpreter)",
            "language": "python",
        }
        (spec_dir / "kernel.json").write_text(json.dumps(spec))
        old = os.environ.get("JUPYTER_PATH")
        os.environ["JUPYTER_PATH"] = tmp + (os.pathsep + old if old else "")
        try:
            yield "course-python"
        finally:
            if old is None:
                os.environ.pop("JUPYTER_PATH", None)
            else:
                os.environ["JUPYTER_PATH"] = old


@contextlib.contextmanager
def _environment(**values):
    old = {k: os.environ.get(k) for k in values}
    os.environ.update({k: str(v) for k, v in values.items()})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def execute(nb, timeout=900, cwd=HERE, small=False, impl=None, progress=None, keep_going=False, verbose=True):
    """Run every cell of ``nb`` in place. A failing cell raises ``nbclient``'s error, or, with
    ``keep_going``, stays in the notebook as its error output and the next cells run
    (``failures(nb)`` lists them). Either way an error shows as one short output where
    ``SHORT_ERRORS`` says so (an unwritten TODO, and the cells after it that need its results).

    The kernel inherits ``COURSE_IMPL = impl`` (None: ``default_impl()``),
    ``COURSE_NOTEBOOK_REPEAT`` (1 when
    ``small``, else 5) and ``COURSE_NOTEBOOK_SMALL`` (1 when ``small``: chapters 2, 3 and 3b
    run on small graphs only, chapter 4 on synthetic problems, chapter 5 on a 4-second
    simulation, chapter 7 on intel alone) and starts in ``cwd``. ``progress``, a name: report each
    cell on stderr under it (see ``_Progress``; ``verbose``: a line per cell off a terminal).
    """
    from nbclient import NotebookClient

    with kernel_for_this_interpreter() as kernel_name, \
            _environment(COURSE_IMPL=impl or default_impl(), COURSE_NOTEBOOK_REPEAT=1 if small else 5,
                         COURSE_NOTEBOOK_SMALL=1 if small else 0):
        report = _Progress(progress, nb, verbose) if progress else None
        client: NotebookClient

        async def short_errors(notebook=None):
            """Before the first cell: install ``SHORT_ERRORS`` in the kernel (silently: no cell, no count)."""
            assert client.kc is not None
            await client.async_wait_for_reply(client.kc.execute(SHORT_ERRORS, silent=True, store_history=False))

        # the outputs are in ``nb`` once the last cell ran: a graceful shutdown only waits, seconds per
        # notebook, for the kernel's interpreter to finalize (CLOSE_RUNTIMES does what matters of it)
        client = NotebookClient(nb, timeout=timeout, kernel_name=kernel_name, allow_errors=keep_going,
                                resources={"metadata": {"path": str(cwd)}}, on_notebook_start=short_errors,
                                on_cell_start=report.on_cell_start if report else None,
                                shutdown_kernel="immediate")
        try:
            with client.setup_kernel():
                client.execute(cleanup_kc=False)
                assert client.kc is not None
                client.wait_for_reply(client.kc.execute(CLOSE_RUNTIMES, silent=True, store_history=False))
        finally:
            if report is not None:
                report.close()
    return nb


def select(names=None) -> dict:
    """``NOTEBOOKS`` restricted to the notebooks whose file name starts with one of ``names``
    (e.g. ``chapter2``); all of them when ``names`` is empty."""
    if not names:
        return dict(NOTEBOOKS)
    chosen = {path: source for path, source in NOTEBOOKS.items() if any(path.name.startswith(n) for n in names)}
    unknown = [n for n in names if not any(path.name.startswith(n) for path in NOTEBOOKS)]
    if unknown:
        raise ValueError(f"no notebook named {unknown}; choose from {[p.stem for p in NOTEBOOKS]}")
    return chosen


def _stderr(line):
    print(line, file=sys.stderr, flush=True)


def build(execute_notebooks=False, small=False, impl=None, out_dir=HERE, only=None, log=None,
          outcomes=None, verbose=False) -> list:
    """Write the notebooks (all, or those ``select(only)`` picks) into ``out_dir``; returns the paths.

    ``impl`` None: ``default_impl()``. An existing notebook's answer cells keep their
    source (``keep_answers``). Executed, a notebook whose cell fails is still written, with that
    cell's error as its output, and the next cells and notebooks still run (``execute(...,
    keep_going=True)``); ``outcomes``, a list, receives ``(path, failures(nb))`` per notebook.
    ``log``, when given, is called with one line per notebook (``outcome``: written, its run time, the
    cells that stopped at a TODO or failed); ``verbose``: also one line per executed cell on stderr
    off a terminal."""
    written = []
    from_source = peers.installed("jupytext")
    if not from_source:
        peers.announce("jupytext")
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    for path, source in select(only).items():
        nb = read(source) if from_source else shipped(path)
        target = Path(out_dir) / path.name
        keep_answers(nb, target)
        start = time.perf_counter()
        if execute_notebooks:
            execute(nb, small=small, impl=impl, progress=path.name, keep_going=True, verbose=verbose)
        nbformat.validate(nb)
        nbformat.write(nb, target)
        written.append(target)
        if outcomes is not None:
            outcomes.append((target, failures(nb)))
        if log is not None:
            log(outcome(f"wrote {target}", nb, time.perf_counter() - start) if execute_notebooks
                else f"wrote {target}")
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m notebooks.build", description=__doc__.splitlines()[0])
    parser.add_argument("--execute", action="store_true", help="run the notebooks and keep their outputs")
    parser.add_argument("--small", action="store_true",
                        help="one run per timing instead of five, small graphs only (quicker)")
    parser.add_argument("--impl", default=None,
                        help="implementation the notebooks use (default: solutions when present, else exercises)")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        help="only these notebooks, by the start of their file name (e.g. chapter2)")
    parser.add_argument("--verbose", action="store_true", help="with --execute: one line per cell on stderr")
    parser.add_argument("--out", metavar="DIR", default=None,
                        help="write the notebooks into DIR (default: notebooks/, beside their sources)")
    args = parser.parse_args(argv)
    outcomes: list = []
    build(args.execute, args.small, args.impl, out_dir=Path(args.out) if args.out else HERE, only=args.only,
          log=_stderr, outcomes=outcomes, verbose=args.verbose)
    todos = sorted({todo_name(line) for _, found in outcomes for _, line in found["todo"]})
    failed = [path.name for path, found in outcomes if found["error"]]
    if todos:
        _stderr(f"not written yet: {', '.join(todos)}; the cells that need them say so, and every other cell "
                "ran (`python -m autograder --only NAME` grades one exercise)")
    if failed:
        _stderr(f"failed: a cell of {', '.join(failed)} raised an error other than a TODO (see its output)")
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
