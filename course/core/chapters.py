"""The course's chapters in order and the framework each adds: the one place that says which is whose.

A chapter's ``paths`` (relative to the repository; a name ending in ``*`` is a prefix) are the
framework it brings beside the earlier chapters': its problem family (``course/problems/FAMILY``),
its peers (``course/backends/FAMILY``), its notebook and notebook helpers, its commands. The tree
of one assignment holds the paths of the chapters up to the latest one whose exercises that
assignment or an earlier one hands out, and no later chapter's: the tree of week 2 has no
chapter-7 engine whose automatic Jacobians would give week 2's answer. The framework tells from
the tree itself whether a chapter is there (:func:`handed_out`), and a command that needs one
that is not says so (:class:`NotHandedOut`).

``exercises`` name the check modules of ``autograder/checks`` (``tests/test_chapters.py`` holds every
one in exactly one chapter); ``families`` the problem kinds of ``course.backends.registry`` and of
``compare`` that the chapter introduces.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from course.core.errors import CourseError
from course.core.impl import REPO_ROOT


@dataclass(frozen=True)
class Chapter:
    """``name`` (``"ch4"``, as the course configuration's assignments), ``title``, the check modules of
    its ``exercises``, the problem kinds it introduces (``families``) and the ``paths`` it adds."""

    name: str
    title: str
    exercises: tuple[str, ...]
    families: tuple[str, ...]
    paths: tuple[str, ...]


CHAPTERS: tuple[Chapter, ...] = (
    Chapter("ch1", "curve fitting", ("curve_model", "gauss_newton", "damping", "end_to_end"), ("curve",),
            ("course/problems/curve", "course/backends/curve", "course/notebook_helpers/chapter1.py",
             "notebooks/chapter1_*")),
    Chapter("ch2", "2D pose graphs",
            ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast",
             "pose_graph"), ("posegraph",),
            ("course/problems/posegraph", "course/backends/posegraph", "course/notebook_helpers/chapter2.py",
             "course/app/benchmark.py", "notebooks/chapter2_*")),
    Chapter("ch3", "Powell's dogleg", ("dogleg",), (),
            ("course/notebook_helpers/chapter3.py", "notebooks/chapter3_*")),
    Chapter("ch3b", "initialisation", ("initialisation",), (),
            ("course/notebook_helpers/chapter3b.py", "notebooks/chapter3b_*")),
    Chapter("ch4", "bundle adjustment", ("bundle_adjustment", "robust_kernels", "gauge", "parallel_assembly"),
            ("bal",),
            ("course/problems/bal", "course/backends/bal", "course/notebook_helpers/bal.py",
             "course/notebook_helpers/chapter4.py", "course/app/benchmark_bal.py", "course/app/parallel_speedup.py",
             "notebooks/chapter4_*")),
    Chapter("ch5", "a visual-inertial back end", ("imu_preintegration", "marginalisation"), ("vio",),
            ("course/problems/vio", "course/backends/vio", "course/notebook_helpers/vio.py",
             "course/notebook_helpers/chapter5.py", "course/app/vio.py", "course/app/benchmark_vio.py",
             "notebooks/chapter5_*")),
    Chapter("ch6", "3D pose graphs", ("pose_graph_3d", "pose_graph_3d_assembly", "chordal_3d", "gnc"),
            ("posegraph3d",),
            ("course/problems/posegraph3d", "course/backends/posegraph3d", "course/notebook_helpers/posegraph3d.py",
             "course/notebook_helpers/chapter6.py", "course/app/benchmark_3d.py", "course/app/outliers3d.py",
             "notebooks/chapter6_*")),
    Chapter("ch7", "the factor graph with automatic differentiation",
            ("jets", "autodiff_factor", "factor_linearisation"), ("factorgraph",),
            ("course/factorgraph", "course/backends/factorgraph", "course/problems/posegraph/factor_graph.py",
             "course/problems/bal/factor_graph.py", "course/problems/posegraph3d/factor_graph.py",
             "course/notebook_helpers/chapter7.py", "course/app/benchmark_autodiff.py", "notebooks/chapter7_*")),
    Chapter("ch8", "elimination, the Bayes tree, marginals and incremental smoothing",
            ("elimination", "orderings", "bayes_tree", "marginal_covariances", "incremental_update"), (),
            ("course/incremental", "course/app/online.py", "course/backends/gtsam_isam2_feed.py",
             "course/backends/posegraph/gtsam_isam2.py",
             "course/backends/posegraph3d/gtsam_isam2.py", "course/marginals", "course/app/marginals.py",
             "course/backends/posegraph/gtsam_marginals.py",
             "course/backends/posegraph/ceres_covariance.py", "course/backends/posegraph3d/gtsam_marginals.py",
             "course/backends/posegraph3d/ceres_covariance.py", "course/backends/factorgraph/gtsam_marginals.py",
             "course/notebook_helpers/chapter8.py", "notebooks/chapter8_*")),
)

BY_NAME = {chapter.name: chapter for chapter in CHAPTERS}


class NotHandedOut(CourseError):
    """A command needs a chapter whose framework this tree does not hold yet."""


def chapter(name: str) -> Chapter:
    """The chapter ``name`` (``"ch4"``), or ``KeyError`` listing the names."""
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"no chapter {name!r}; the chapters: {', '.join(BY_NAME)}") from None


def of_exercise(exercise: str) -> Chapter:
    """The chapter whose exercises hold the check module ``exercise``."""
    for one in CHAPTERS:
        if exercise in one.exercises:
            return one
    raise KeyError(f"no chapter holds the exercise {exercise!r}")


def of_family(family: str) -> Chapter:
    """The chapter that introduces the problem kind ``family`` (``"bal"``)."""
    for one in CHAPTERS:
        if family in one.families:
            return one
    raise KeyError(f"no chapter introduces the problem kind {family!r}")


def up_to(exercises) -> tuple[Chapter, ...]:
    """The chapters up to the latest one holding any of ``exercises`` (check module names)."""
    last = max((CHAPTERS.index(of_exercise(name)) for name in exercises), default=-1)
    return CHAPTERS[:last + 1]


def files(one: Chapter, root: Path = REPO_ROOT) -> list[str]:
    """The paths of ``one`` present under ``root``, the prefixes expanded (relative, sorted)."""
    out = []
    for rel in one.paths:
        if rel.endswith("*"):
            parent, prefix = Path(rel).parent, Path(rel).name[:-1]
            out += [f"{parent.as_posix()}/{p.name}" for p in sorted(Path(root, parent).glob(prefix + "*"))]
        elif Path(root, rel).exists():
            out.append(rel)
    return out


def handed_out(name: str, root: Path = REPO_ROOT) -> bool:
    """Whether this tree holds chapter ``name``'s framework (every one of its paths that is not a prefix)."""
    return all(Path(root, rel).exists() for rel in chapter(name).paths if not rel.endswith("*"))


def require(name: str, what: str = "") -> None:
    """``NotHandedOut`` naming the chapter (and ``what`` needed it) when this tree does not hold it."""
    if not handed_out(name):
        one = chapter(name)
        need = f"{what} needs " if what else ""
        raise NotHandedOut(f"{need}chapter {name[2:]} ({one.title}), which is not handed out yet in this tree")
