"""The registry of checks: one module per exercise module, named after it
(``checks/damping.py`` grades ``exercises/damping.py``), plus ``end_to_end.py`` for the
runs that use several pieces together, and ``common.py`` for the helpers several share.

A check is a :class:`Check`: a ``name`` (unique, ``"<exercise>: <title>"``), the
``exercise`` it belongs to (partial credit per exercise is the sum of its checks),
``points``, ``calls(seed)`` (the list of :class:`Call` the child runs with the student's
implementation: ``seed=None`` gives the public inputs, an integer fresh hidden inputs of
the same kind) and ``judge``, a function in the parent that turns a :class:`Context`
(the calls, the student's raw outputs, the reference's outputs and the known mistakes'
outputs on the same inputs) into a :class:`Verdict` (fraction of the points earned,
feedback). Helpers for judges are in :mod:`autograder.feedback`.

Nothing here computes a reference answer: the reference outputs and the known mistakes
(``autograder/mistakes/<module>.py``, instructor only) come from :mod:`autograder.oracle`
on the instructor's side, and from the shipped data (:mod:`autograder.expected`) for the
public checks. An input builder that needs a reference output (e.g. the reference edge
Jacobians fed to the assembly) imports it through ``autograder.oracle`` inside the
builder, so it only ever runs on the instructor's side.

To add an exercise, write ``autograder/checks/<module>.py`` with ``MODULES`` (the
implementation modules it grades) and ``CHECKS``, and add its name to :data:`ORDER`.
A call's ``target`` is ``"module:qualname"`` inside the implementation
(``"damping:GavinType1.update"``: the class is instantiated with ``init`` first), or
``"@package.module:function"`` for a framework function that the child calls with
``impl=<the student's implementation>`` (see :mod:`autograder.tasks`).
"""

import difflib
import importlib

from autograder.records import Call, Check, Context, ErrorInfo, Outcome, Verdict  # noqa: F401 (re-exported)

#: check modules in report order
ORDER = ("curve_model", "gauss_newton", "damping", "end_to_end", "pose_graph_edge", "pose_graph_assembly",
         "sparse_solve", "ceres_edge_cost", "pose_graph_fast", "pose_graph", "dogleg",
         "initialisation", "bundle_adjustment", "robust_kernels", "gauge", "parallel_assembly",
         "imu_preintegration", "marginalisation", "pose_graph_3d", "pose_graph_3d_assembly", "chordal_3d", "gnc",
         "jets", "autodiff_factor", "factor_linearisation",
         "elimination", "orderings", "bayes_tree", "marginal_covariances",
         "incremental_update")


def present() -> tuple:
    """The names of :data:`ORDER` whose module is here: all of them, but in an assignment's tree
    (``autograder/ASSIGNMENT``) the check modules of later assignments are not shipped."""
    from pathlib import Path

    here = Path(__file__).resolve().parent
    if not (here.parent / "ASSIGNMENT").is_file():
        return ORDER
    return tuple(name for name in ORDER if (here / f"{name}.py").is_file())


#: each check module's chapter, and each chapter's lesson (its notebook, ``make notebooks``): where the
#: grader sends a student whose exercise is at full marks (``autograder.report.next_step``)
CHAPTER = {"curve_model": "1", "gauss_newton": "1", "damping": "1", "end_to_end": "1",
           "pose_graph_edge": "2", "pose_graph_assembly": "2", "sparse_solve": "2", "ceres_edge_cost": "2",
           "pose_graph_fast": "2", "pose_graph": "2", "dogleg": "3", "initialisation": "3b",
           "bundle_adjustment": "4", "robust_kernels": "4", "gauge": "4", "parallel_assembly": "4",
           "marginalisation": "5", "imu_preintegration": "5",
           "pose_graph_3d": "6", "pose_graph_3d_assembly": "6", "chordal_3d": "6", "gnc": "6",
           "jets": "7", "autodiff_factor": "7", "factor_linearisation": "7",
           "elimination": "8", "orderings": "8", "bayes_tree": "8", "marginal_covariances": "8",
           "incremental_update": "8"}
LESSONS = {"1": "notebooks/chapter1_curve_fitting.ipynb", "2": "notebooks/chapter2_pose_graphs.ipynb",
           "3": "notebooks/chapter3_dogleg.ipynb", "3b": "notebooks/chapter3b_initialisation.ipynb",
           "4": "notebooks/chapter4_bundle_adjustment.ipynb", "5": "notebooks/chapter5_vio.ipynb",
           "6": "notebooks/chapter6_pose_graphs_3d.ipynb", "7": "notebooks/chapter7_factor_graphs.ipynb",
           "8": "notebooks/chapter8_elimination.ipynb"}


def modules() -> list:
    """``(name, module)`` of every check module, in report order."""
    return [(name, importlib.import_module(f"{__name__}.{name}")) for name in present()]


def module_of() -> dict:
    """``{check name: check module name}``."""
    return {check.name: name for name, module in modules() for check in module.CHECKS}


def all_checks() -> list:
    checks = [check for _, module in modules() for check in module.CHECKS]
    seen = set()
    for check in checks:
        if check.name in seen:
            raise ValueError(f"duplicate check name {check.name!r}")
        seen.add(check.name)
    return checks


class SelectionError(ValueError):
    """An ``--only`` name that selects nothing; the message lists the close names."""


def names(checks: list) -> list:
    """Every name ``--only`` takes for ``checks``: check modules, exercises and check names, in order."""
    owner = module_of()
    out: list = []
    for check in checks:
        for name in (owner.get(check.name, ""), check.exercise, check.name):
            if name and name not in out:
                out.append(name)
    return out


def select(checks: list, only) -> list:
    """The checks named by ``only``: each name an exact check module (``damping``, ``pose_graph``: the
    checks that grade that exercise file or run those pieces together), exercise
    (``damping.GavinType1``, ``pose_graph.end_to_end``) or check name. No prefixes: ``pose_graph``
    is not ``pose_graph_3d``. A name that matches none of ``checks`` raises :class:`SelectionError`
    naming the close ones (difflib)."""
    if not only:
        return list(checks)
    owner = module_of()
    chosen = set()
    for name in only:
        hits = [check.name for check in checks if name in (owner.get(check.name), check.exercise, check.name)]
        if not hits:
            known = names(checks)
            near = difflib.get_close_matches(name, known, n=6, cutoff=0.6)
            near = (near + [k for k in known if k.startswith(name) and k not in near])[:6]
            exercises = [k for k in known if k in ORDER]
            hint = f"; close: {', '.join(near)}" if near else f"; the check modules: {', '.join(exercises)}"
            raise SelectionError(f"--only {name!r} matches no check module, exercise or check{hint}")
        chosen.update(hits)
    return [check for check in checks if check.name in chosen]
