"""A factor graph's mistakes, named: two factor types of one name, a key that was never added, a
non-finite residual or Jacobian (its factor, type and keys), and a free gauge under Gauss-Newton."""

import numpy as np
import pytest

from course.core.errors import NonFiniteError, SingularSystemError
from course.factorgraph import BETWEEN_SE2, SE2, FactorGraph, FactorGraphProblem, FactorType
from course.solver import SolverOptions, minimize


def _chain(n=3, fixed=True):
    graph = FactorGraph("chain")
    for k in range(n):
        graph.add_variable(f"x{k}", SE2, [k, 0.0, 0.1 * k])
    if fixed:
        graph.fix("x0")
    for k in range(n - 1):
        graph.add(BETWEEN_SE2, [f"x{k}", f"x{k + 1}"], [1.0, 0.0, 0.0])
    return graph


def test_two_factor_types_of_one_name_are_an_error_naming_both():
    graph = _chain()
    other = FactorType("between_se2", BETWEEN_SE2.kinds, 3, lambda z, a, b: b - a - z)
    with pytest.raises(ValueError, match=r"two factor types are named 'between_se2' \(residuals "
                                         r"course\.factorgraph\.factors\.between_se2 and .*<lambda>\)"):
        graph.add(other, ["x0", "x2"], [2.0, 0.0, 0.0])
    graph.add(BETWEEN_SE2, ["x0", "x2"], [2.0, 0.0, 0.0])  # the same type again joins its group
    assert graph.num_factors == 3 and len(graph.groups) == 1


def test_an_integer_is_a_key_not_an_index():
    graph = _chain()
    with pytest.raises(ValueError, match=r"^chain: between_se2: no variable 0 \(keys are the names"):
        graph.add(BETWEEN_SE2, [0, 2], [2.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="no variable 1"):
        graph.fix(1)
    graph.add_many(BETWEEN_SE2, np.array([[0, 2]]), np.array([[2.0, 0.0, 0.0]]))  # an index array is indices
    assert graph.num_factors == 3


@pytest.mark.parametrize("jacobians", ["autodiff", "numeric"])
def test_a_non_finite_residual_names_its_factor_type_and_keys(jacobians):
    graph = _chain(5)
    log_x = FactorType("log_x", (SE2,), 1, lambda z, x: np.log(x[..., :1] - 3.0) - z)
    graph.add_many(log_x, [["x4"], ["x3"], ["x2"]], np.zeros((3, 1)))
    problem = FactorGraphProblem(graph, jacobians=jacobians)
    with pytest.raises(NonFiniteError, match=r"non-finite r for factor 1 of type 'log_x' on 'x3' \(chain\): "
                                             r"r\[1, 0\] = -?(nan|inf)"):
        with np.errstate(all="ignore"):
            problem.linearize(problem.x0)


def test_a_free_gauge_under_gauss_newton_says_which_part_is_free():
    graph = _chain(4, fixed=False)
    with pytest.raises(SingularSystemError, match=r"The gauge is free: the 4 variable\(s\) joined to 'x0' have no "
                                                  r"fixed variable and no prior.*graph\.fix\('x0'\)"):
        minimize(FactorGraphProblem(graph), "gauss-newton", options=SolverOptions(max_iterations=3))
    assert FactorGraphProblem(_chain(4)).free_gauges() == []
    two_parts = _chain(4)
    two_parts.add_variable("y0", SE2, [0.0, 5.0, 0.0])
    two_parts.add_variable("y1", SE2, [1.0, 5.0, 0.0])
    two_parts.add(BETWEEN_SE2, ["y0", "y1"], [1.0, 0.0, 0.0])
    assert FactorGraphProblem(two_parts).free_gauges() == [(2, "y0")]
