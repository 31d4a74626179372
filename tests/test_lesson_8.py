"""Chapter 8's lesson: the helpers of its theory and experiments (``course.notebook_helpers.chapter8``), the
notebook run in the quick setting (a hint, a check and a checker per exercise, the figures, the written
questions), its reference answers, and the notebook in a student tree where nothing of chapter 8 is written."""

from types import SimpleNamespace

import nbformat
import numpy as np
import pytest
from executed_notebooks import (
    assert_hints_and_checks_at_full_marks,
    assert_no_level_3_hint_line,
    cell_text,
    chapter_1_student_build,
    executed_small,
)

from course.core import peers
from course.core.impl import REPO_ROOT
from course.notebook_helpers import chapter8
from notebooks import build

EXERCISES = ("elimination", "orderings", "bayes_tree", "marginal_covariances", "incremental_update")
FIGURES = ["figure-game", "figure-ellipses", "figure-online"]


def _module(name):
    return chapter8.exercise(name, "solutions")


# ---------------------------------------------------------------- the helpers of the theory


def test_one_elimination_is_checked_by_the_split_it_promises():
    module = _module("elimination")
    lines = []
    assert chapter8.elimination_check(module, out=lines.append)
    assert "R upper triangular: yes" in lines[0] and "a constant c >= 0, right" in lines[1]

    def wrong(A_x, A_s, b):  # the conditional's S forgotten: the split no longer holds
        R, S, d, A_new, b_new = module.eliminate_variable(A_x, A_s, b)
        return R, 0.0 * S, d, A_new, b_new

    lines = []
    assert not chapter8.elimination_check(SimpleNamespace(eliminate_variable=wrong), out=lines.append)
    assert "NOT a constant" in lines[1]


def test_the_stacked_factors_of_a_variable_and_its_separator():
    graph = chapter8.small_graph()
    A_x, A_s, b, separator = chapter8.stacked(graph, 0)
    assert separator == [1, 2] and A_x.shape == (6, 2) and A_s.shape == (6, 4) and b.shape == (6,)
    assert not np.any(A_s[:2])  # the prior on x0 touches no separator variable
    A_x, A_s, b, separator = chapter8.stacked(graph, 2)
    assert separator == [0, 1] and A_x.shape == (5, 2)


def test_back_substitution_through_the_bayes_net_is_the_least_squares_solution():
    module = _module("elimination")
    graph = chapter8.small_graph(seed=3)
    want = np.concatenate(chapter8.least_squares(graph))
    for ordering in ([0, 1, 2], [2, 0, 1], [1, 2, 0]):
        net = chapter8.eliminate_all(module, graph, ordering)
        assert [v for v, *_ in net] == ordering and net[-1][1] == []  # the last one has no separator
        np.testing.assert_allclose(np.concatenate(chapter8.back_substitute(net, graph.sizes)), want, rtol=0,
                                   atol=1e-12)
    text = chapter8.bayes_net_table(module)
    assert "p(x0 | x1, x2), p(x1 | x2), p(x2)" in text and "p(x1 | x0, x2), p(x0 | x2), p(x2)" in text


def test_the_elimination_game_figure_and_its_fill():
    module = _module("orderings")
    n, edges, _ = chapter8.game_graph()
    fills = {name: len(np.asarray(module.symbolic_elimination(n, edges, order)[2]).reshape(-1, 2))
             for name, order in (("natural", np.arange(n)),
                                 ("minimum degree", module.minimum_degree_ordering(n, edges)))}
    assert fills == {"natural": 7, "minimum degree": 4}
    fig = chapter8.game_figure(module)
    assert [ax.get_title().splitlines()[0] for ax in fig.axes] == ["natural: 7 fill edge(s), 1 root(s)",
                                                                   "minimum degree: 4 fill edge(s), 1 root(s)"]


def test_the_bayes_tree_of_the_game_and_its_properties():
    lines = []
    assert chapter8.bayes_tree_check(_module("orderings"), _module("bayes_tree"), out=lines.append)
    assert lines[:4] == ["clique 0: 3 4 5 7 : (root)", "    clique 1: 2 : 3 5", "        clique 2: 1 6 : 2 5",
                         "            clique 3: 0 : 1 6 5"]

    def flat(ordering, separators):  # every clique hung under the root: the running intersection fails
        frontals, seps, parents = _module("bayes_tree").bayes_tree(ordering, separators)
        return frontals, seps, [p if p < 0 else 0 for p in parents]

    lines = []
    assert not chapter8.bayes_tree_check(_module("orderings"), SimpleNamespace(bayes_tree=flat), out=lines.append)
    assert "parent's variables: NO" in lines[-1]


def test_the_incremental_update_on_the_game_tree_and_its_properties():
    orderings, bayes, incremental = (_module(name) for name in ("orderings", "bayes_tree", "incremental_update"))
    lines: list = []
    assert chapter8.affected_check(orderings, bayes, incremental, out=lines.append)
    assert lines[0].startswith("a measurement between poses 4 and 5: top [0] (re-eliminates [3, 4, 5, 7]), "
                               "orphans [1];")
    assert "top [0, 1] (re-eliminates [2, 3, 4, 5, 7]), orphans [2]" in lines[2]  # pose 3: root and separator
    assert "top [0, 1, 2, 3]" in lines[3]  # pose 1 is in clique 3's separator only
    lines = []
    assert chapter8.wildfire_check(orderings, bayes, incremental, out=lines.append)
    assert "recomputed 4 of 4 cliques" in lines[0] and "the others kept their steps: yes" in lines[1]

    def frontals_only(frontals, clique_separators, parents, new_keys, relinearised):  # the separator forgotten
        return incremental.affected_cliques(frontals, [[] for _ in frontals], parents, new_keys, relinearised)

    lines = []
    assert not chapter8.affected_check(orderings, bayes, SimpleNamespace(affected_cliques=frontals_only),
                                       out=lines.append)
    assert "holds the marked cliques: NO" in lines[3]

    def every_clique(frontals, clique_separators, parents, conditionals, delta, replaced, threshold):
        return incremental.wildfire_update(frontals, clique_separators, parents, conditionals, delta,
                                           range(len(frontals)), 0.0)  # recomputes all: right, but not a wildfire

    lines = []
    assert chapter8.wildfire_check(orderings, bayes, SimpleNamespace(wildfire_update=every_clique),
                                   out=lines.append)  # the properties hold: the checks judge the threshold

    def in_place(frontals, clique_separators, parents, conditionals, delta, replaced, threshold):
        new, recomputed = incremental.wildfire_update(frontals, clique_separators, parents, conditionals, delta,
                                                      replaced, threshold)
        return [step + 1e-3 for step in new], recomputed  # a step that no conditional gives

    lines = []
    assert not chapter8.wildfire_check(orderings, bayes, SimpleNamespace(wildfire_update=in_place),
                                       out=lines.append)
    assert "(WRONG)" in lines[0]


def test_orderings_on_a_generated_graph(tmp_path):
    module = _module("orderings")
    n, edges = chapter8.graph_of("manhattan:200")
    rows = {row[0]: row for row in chapter8.ordering_rows(module, n, edges)}
    natural, minimum = rows["natural"], rows["minimum degree (yours)"]
    assert minimum[2] < natural[2] and minimum[5] < natural[5]  # less fill, fewer nonzeros in R
    assert ("AMD (SuiteSparse, cvxopt)" in rows) == peers.installed("cvxopt")
    # R's nonzeros: 6 per diagonal block and 9 per separator pose
    separators, _, _ = module.symbolic_elimination(n, edges, np.arange(n))
    assert natural[5] == 6 * n + 9 * sum(len(s) for s in separators)


def test_marginals_on_a_generated_graph_are_the_dense_inverses_blocks():
    info = chapter8.pose_graph_information("manhattan:150", "solutions")
    run = chapter8.marginals_run(info, _module("orderings"), _module("marginal_covariances"))
    assert run["n"] == 150 and run["worst"] < 1e-9
    np.testing.assert_allclose(run["covariances"][0], np.eye(3), atol=1e-12)  # the pose held still
    assert "150 poses: marginals by your recursion" in chapter8.marginals_line(run)
    fig = chapter8.ellipse_figure(info, run["covariances"])
    assert "3-sigma position ellipses" in fig.axes[0].get_title()


# ---------------------------------------------------------------- the notebook


_outputs = cell_text


def _images(nb) -> list:
    return [c.id for c in nb.cells if c.cell_type == "code" for o in c.outputs if "image/png" in o.get("data", {})]


@pytest.fixture(scope="module")
def executed():
    from course.core.data import data_dir

    if not data_dir().is_dir():
        pytest.skip(f"data folder {data_dir()} not found (set COURSE_DATA to use another)")
    return executed_small(build.CHAPTER8)


@pytest.mark.slow
def test_the_lesson_runs_with_a_hint_a_check_and_a_checker_per_exercise(executed):
    nb = executed
    text = _outputs(nb)
    assert_hints_and_checks_at_full_marks(nb, (("hint-elimination", "check-elimination", "elimination"),
                                               ("hint-orderings", "check-orderings", "orderings"),
                                               ("hint-bayes-tree", "check-bayes-tree", "bayes_tree"),
                                               ("hint-marginals", "check-marginals", "marginal_covariances"),
                                               ("hint-incremental", "check-incremental", "incremental_update")))
    order = [c.id for c in nb.cells]
    assert order.index("eliminate-md") < order.index("elimination-check") < order.index(
        "check-elimination") < order.index("orderings-md") < order.index("check-orderings") < order.index(
        "bayes-tree-md") < order.index("bayes-tree-check") < order.index("check-bayes-tree") < order.index(
        "marginals-md") < order.index("marginals-check") < order.index("check-marginals") < order.index(
        "incremental-md") < order.index("incremental-check") < order.index("check-incremental")
    assert "a constant c >= 0, right" in text["elimination-check"]
    assert "|x - x_lstsq| = " in text["bayes-net"]
    assert "intel          minimum degree (yours)" in text["fill-table"]
    assert "clique 0: 3 4 5 7 : (root)" in text["bayes-tree-check"] and "parent's variables: yes" in text[
        "bayes-tree-check"]
    assert "150 poses: marginals by your recursion" in text["marginals-check"]
    assert "729 poses: marginals by your recursion" in text["marginals-intel"]
    assert "orphans hang from it: yes" in text["incremental-check"] and "(fine)" in text["incremental-check"]
    assert "ours (incremental)             300" in text["online"] and "GTSAM ISAM2" in text["online"]
    assert "ours, the last update iterated to convergence" in text["online"]
    assert _images(nb) == FIGURES
    assert_no_level_3_hint_line("\n".join(c.source for c in nb.cells) + "\n".join(text.values()), EXERCISES)


def test_the_written_questions_and_their_answer_cells():
    nb = build.read(build.NOTEBOOKS[build.CHAPTER8])
    markdown = {c.id: c for c in nb.cells if c.cell_type == "markdown"}
    assert list(markdown)[-7] == "questions-md"
    for k in range(1, 7):
        assert f"**Question {k}.**" in markdown["questions-md"].source
        cell = markdown[f"answer-{k}"]
        assert cell.metadata["tags"] == [build.ANSWER_TAG] and f"Your answer to question {k}" in cell.source
    title = markdown["title"].source
    for words in ("Theory", "Experiments", "Written questions", "hint(", "python -m autograder hint NAME LEVEL",
                  "Conventions", "whitened"):
        assert words in title, words


def test_reference_answers_stay_out_of_the_student_tree():
    from autograder.release import stubs as release

    answers = (REPO_ROOT / "solutions" / "answers" / "chapter8.md").read_text()
    assert answers.startswith("# RELEASE: omit")
    for k in range(1, 7):
        assert f"## Question {k}:" in answers
    assert not [name for name in release.render(REPO_ROOT / "solutions") if name.startswith("answers")]


def test_the_lesson_is_registered():
    from autograder.checks import CHAPTER, LESSONS

    assert LESSONS["8"] == "notebooks/chapter8_elimination.ipynb"
    assert {CHAPTER[name] for name in EXERCISES} == {"8"}
    assert build.NOTEBOOKS[build.CHAPTER8] == REPO_ROOT / "notebooks" / "chapter8_elimination.py"


@pytest.mark.slow
def test_in_a_student_tree_the_lesson_builds_and_names_its_todos(python):
    built = chapter_1_student_build(python)  # the tree (chapter 1 written) and every notebook, once per run
    assert built["returncode"] == 0, built["output"][-3000:]
    nb = nbformat.read(built["out"] / "chapter8_elimination.ipynb", as_version=4)
    text = _outputs(nb)
    assert "implementation: exercises" in text["setup"]
    for c in nb.cells:
        for o in c.get("outputs", []):
            assert o.output_type != "error", (c.id, o.get("traceback"))
    for check_id in ("check-elimination", "check-orderings", "check-bayes-tree", "check-marginals",
                     "check-incremental"):
        assert "reach a TODO" in text[check_id], text[check_id]
    for cell_id in ("elimination-check", "bayes-net", "figure-game", "fill-table", "bayes-tree-check",
                    "marginals-check", "marginals-intel", "incremental-check"):
        lines = text[cell_id].strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("not implemented: TODO ") and len(lines[0]) < 200, (
            cell_id, lines)
    for hint_id in ("hint-elimination", "hint-orderings", "hint-bayes-tree", "hint-marginals", "hint-incremental"):
        assert "hint 1 of 3" in text[hint_id]
