"""Checks of ``factor_linearisation`` (chapter 7): the block-sparse H, b and chi2 of a factor graph
whose variables have mixed tangent sizes, into a pattern found once.

The assembler is built once and called twice with other numbers on the same pattern (the minimizer
calls it every iteration). The blocks are random: whitened residuals and Jacobian blocks, as the
linearisation hands them over. Public inputs: a 2D graph of three SE(2) poses and two landmarks
(between factors, one from a later to an earlier pose; range-bearing factors; a prior on one pose,
a factor of one variable; two factors on the same two poses), pose 0 fixed; a graph of two SE(3)
poses, two 3D points and a rotation (6, 3 and 3 tangent sizes) with no fixed variable, each pose in
8 point factors (as a camera in bundle adjustment, where summing by variable pays); one factor on
one variable (each its own check: the assembler's judge reads one call).
Hidden: other numbers and keys from the hidden seed, same structure. H is compared as
a dense matrix of its upper triangle (1e-10 of its largest entry), b and chi2 to 1e-9.
"""

from functools import cache

import numpy as np

from autograder.checks import Call
from autograder.checks.common import assembler_judge, check
from autograder.checks.edges import Edge

MODULES = ("factor_linearisation",)
NAME = "factor_linearisation.BlockSparseAssembler"
TASK = "@autograder.tasks.factor_linearisation:assemble_task"


def _blocks(rng, dims, keys, m):
    """``(r (M, m), [J_a (M, m, d_a)])`` of one group."""
    keys = np.asarray(keys)
    return (rng.normal(0.0, 1.0, (len(keys), m)),
            [rng.normal(0.0, 1.0, (len(keys), m, dims[keys[0, a]])) for a in range(keys.shape[1])])


def _graph(rng, dims, groups, fixed, where, hidden):
    if hidden:  # the same structure, other variables in each slot (kinds kept)
        groups = [(_shuffle(rng, dims, keys), m) for keys, m in groups]
    keys = [np.asarray(k, dtype=np.int64) for k, _ in groups]
    calls = [[_blocks(rng, dims, k, m) for k, (_, m) in zip(keys, groups)] for _ in range(2)]
    return Call(TASK, (np.asarray(dims), keys, np.asarray(fixed, dtype=np.int64), calls), returns="dict",
                where=where, label=NAME)


def _shuffle(rng, dims, keys):
    """``keys`` with each slot's variables redrawn among the variables of the same size."""
    original = np.array(keys)
    keys = original.copy()
    dims = np.asarray(dims)
    for a in range(keys.shape[1]):
        same = np.flatnonzero(dims == dims[keys[0, a]])
        keys[:, a] = rng.choice(same, len(keys))
    for row, before in zip(keys, original):  # a factor's variables stay distinct
        if len(set(row)) < len(row):
            row[:] = before
    return keys


@cache
def mixed(seed=None):
    rng = np.random.default_rng(71 if seed is None else [seed, 313, 1])
    dims2 = [3, 3, 2, 3, 2]  # poses 0, 1, 3 (SE(2)); landmarks 2, 4
    between = ([[0, 1], [3, 1], [3, 0], [0, 1]], 3)  # later-to-earlier edges; two edges on poses 0, 1
    ranges = ([[0, 2], [1, 2], [3, 4]], 2)
    prior = ([[1]], 3)
    dims3 = [6, 3, 6, 3, 3]  # SE(3) poses 0, 2; points 1, 3; a rotation 4
    poses = ([[0, 2], [2, 0]], 6)
    points = ([[0, 1], [2, 1], [2, 3], [0, 3]] * 4, 2)  # each pose in 8 of them: a camera seeing many points
    rotation = ([[4, 2]], 3)
    hidden = seed is not None
    return {"2d": [_graph(rng, dims2, [between, ranges, prior], [0],
                          "on 3 SE(2) poses and 2 landmarks (between, range-bearing and prior factors), pose 0 fixed",
                          hidden)],
            "3d": [_graph(rng, dims3, [poses, points, rotation], [],
                          "on 2 SE(3) poses, 2 points and a rotation (tangent sizes 6, 3, 3), no variable fixed",
                          hidden)]}


def planar(seed=None):
    return mixed(seed)["2d"]


def spatial(seed=None):
    return mixed(seed)["3d"]


@cache
def fixed_poses(seed=None):
    rng = np.random.default_rng(72 if seed is None else [seed, 313, 2])
    dims = [3, 2, 3, 3, 2]
    groups = [([[0, 2], [2, 3], [3, 0]], 3), ([[0, 1], [3, 4], [2, 1]], 2)]
    return [_graph(rng, dims, groups, [2, 4], "with variables 2 (a pose) and 4 (a landmark) fixed",
                   seed is not None)]


@cache
def smallest(seed=None):
    rng = np.random.default_rng(73 if seed is None else [seed, 313, 3])
    return [_graph(rng, [6], [([[0]], 6)], [], "on one factor (M = 1) of one variable (N = 1)", False)]


CAUSE = ("a factor adds J_a^T J_c to the block of H at (its variable in slot a, its variable in slot c) for "
         "every pair of slots, J_a^T r to b at slot a's variable, and r^T r to chi2; H is returned as its "
         "upper triangle")
OWNER = "course.factorgraph.problem.FactorGraphProblem"

CHECKS = [
    check(NAME, "H, b and chi2 of poses and landmarks", 2, planar, assembler_judge(CAUSE, OWNER)),
    check(NAME, "H, b and chi2 of variables of mixed sizes", 3, spatial, assembler_judge(CAUSE, OWNER)),
    check(NAME, "fixed variables held still", 2, fixed_poses, assembler_judge(CAUSE, OWNER)),
    check(NAME, "one factor of one variable", 1, smallest, assembler_judge(CAUSE, OWNER)),
]


def _keys(call):
    return call.args[1]


EDGES = (
    Edge("one factor (M = 1) of one variable (N = 1)", TASK, lambda c: len(c.args[0]) == 1),
    Edge("a factor of one variable (a prior)", TASK, lambda c: any(k.shape[1] == 1 for k in _keys(c))),
    Edge("a factor from a later variable to an earlier one", TASK,
         lambda c: any(k.shape[1] > 1 and np.any(k[:, 0] > k[:, 1]) for k in _keys(c))),
    Edge("two factors on the same variables (their blocks add up)", TASK,
         lambda c: any(len({tuple(r) for r in k}) < len(k) for k in _keys(c))),
    Edge("no variable fixed", TASK, lambda c: len(c.args[2]) == 0),
    Edge("a fixed variable that is not the first", TASK, lambda c: any(v > 0 for v in c.args[2])),
)
