"""Chapter 2 checks: the pose-graph edge, the assembly of H and b, the dense and sparse
solves, the Ceres cost of one edge, the vectorized linearization (optional) and a
Gauss-Newton run on a pose graph with the student's loop pieces.

Each piece is graded alone: the assembly runs with the reference error and Jacobians
of every edge standing in for the student's ``pose_graph_edge`` (see
``autograder.tasks.assemble_with_reference_edges``), the sparse solver gets matrices
made here, the Ceres cost is compared with the reference cost. The end-to-end run uses
all of the student's loop pieces together (edge, assembly, sparse solve).
"""

from functools import lru_cache

import numpy as np

from autograder.checks import Call, Check, Verdict
from autograder.compare import _TODO, call_fields, compare, first_error, fmt, values

MODULES = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast")

EDGE = "pose_graph_edge.edge_error_and_jacobians"
ASSEMBLY = "pose_graph_assembly.assemble_normal_equations"
DENSE = "sparse_solve.dense_solve"
UPPER = "sparse_solve.upper_triangle_csc"
SPARSE = "sparse_solve.SparseCholeskySolver"
CERES = "ceres_edge_cost.SE2EdgeCost"
FAST_EDGES = "pose_graph_fast.edge_errors_and_jacobians"
FAST_ASSEMBLER = "pose_graph_fast.SparseAssembler"
END = "pose_graph.end_to_end"

LOOP_NOTE = "[the per-edge loop works]"

# ---------------------------------------------------------------- helpers


def _wrap(angle):
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def _rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def _drot_t(theta):
    """d R(theta)^T / d theta."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[-s, c], [-c, -s]])


def _drot(theta):
    """d R(theta) / d theta (the derivative of the wrong matrix)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[-s, -c], [c, -s]])


def _block(top_left, column, corner):
    M = np.zeros((3, 3))
    M[:2, :2] = top_left
    M[:2, 2] = column
    M[2, 2] = corner
    return M


def _pose(x):
    return fmt(np.asarray(x, dtype=float))


def _solutions(module):
    from course import impl as impl_loader

    return impl_loader.load("solutions").module(module)


def _failed(ctx, hints=None):
    """``first_error`` naming every TODO stub met (a constructor stub hides its methods')."""
    verdict = first_error(ctx, hints)
    if verdict is None or not verdict.not_implemented:
        return verdict
    names, loop = list(verdict.not_implemented), False
    for outcome in ctx.student:
        if outcome.error is not None:
            loop = loop or LOOP_NOTE in outcome.error.message
            for name in _TODO.findall(outcome.error.message):
                if name not in names:
                    names.append(name)
    message = verdict.message
    if loop:
        message += (" (optional, going further: without it PoseGraphProblem falls back to your "
                    "per-edge loop pose_graph_assembly, fine for small graphs)")
    return Verdict(0.0, message, tuple(names))


def _values(*args, **kwargs):
    """``autograder.compare.values``, naming every TODO stub met (see ``_failed``)."""
    judge = values(*args, **kwargs)

    def wrapped(ctx):
        return _failed(ctx, kwargs.get("errors")) or judge(ctx)

    return wrapped


# ---------------------------------------------------------------- one edge


@lru_cache(maxsize=None)
def _edges():
    """(x_i, x_j, z_ij, where): generic edges, raw angle errors outside [-pi, pi) and near its ends,
    a measured angle near pi, and two seeded random edges."""
    cases = [
        ((1.2, -0.7, 0.4), (2.5, 0.3, 1.1), (1.1, 0.6, 0.5), ""),
        ((-3.1, 2.0, -2.2), (-1.0, -0.5, 2.9), (-1.5, -2.0, 1.8), "theta_j - theta_i - theta_ij = 3.3 > pi"),
        ((0.5, 0.5, 3.0), (1.5, -0.2, -3.0), (-0.9, 0.4, 0.2), "theta_j - theta_i - theta_ij = -6.2 < -pi"),
        ((2.0, 1.0, -1.0), (2.3, 1.8, 2.1), (0.8, 0.1, 3.05), "theta_ij = 3.05, near pi"),
        ((0.0, 0.0, 1.6), (1.0, 1.0, -1.6), (1.0, -1.0, -0.1), "theta_j - theta_i - theta_ij = -3.1, just above -pi"),
        ((0.3, -1.2, -1.5), (-0.4, 0.9, 1.0), (0.7, 1.9, 2.5 - np.pi - 0.02),
         "theta_j - theta_i - theta_ij = pi + 0.02, just above pi"),
    ]
    rng = np.random.default_rng(3)
    for _ in range(2):  # two seeded random edges
        x_i, x_j, z = (np.round(np.append(rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)), 3) for _ in range(3))
        cases.append((tuple(x_i), tuple(x_j), tuple(z), "random"))
    out = []
    for x_i, x_j, z, note in cases:
        x_i, x_j, z = (np.array(v, dtype=float) for v in (x_i, x_j, z))
        where = f"for x_i = {_pose(x_i)}, x_j = {_pose(x_j)}, z_ij = {_pose(z)}" + (f" ({note})" if note else "")
        out.append((x_i, x_j, z, where))
    return out


def _edge_call(x_i, x_j, z, where):
    return Call("pose_graph_edge:edge_error_and_jacobians", (x_i, x_j, z), returns=("e", "A", "B"), where=where)


def _edge_calls():
    return [_edge_call(*edge) for edge in _edges()]


def _edge_parts(call):
    x_i, x_j, z = call.args
    dt = x_j[:2] - x_i[:2]
    return x_i, x_j, z, dt, _rot(x_i[2]), _rot(z[2])


def _judge_edge_shapes(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    for call, got, _ in triples:
        for name, shape in (("e", (3,)), ("A", (3, 3)), ("B", (3, 3))):
            if got[name].shape != shape:
                text = f"{name} has shape {got[name].shape}, expected {shape} {call.where}"
                if got[name].size == int(np.prod(shape)):
                    text += ": same numbers, wrong shape (reshape it)"
                return Verdict(0.0, text)
    return Verdict(1.0, "ok")


def _e_mistakes(call, ref):
    x_i, x_j, z, dt, Ri, Rz = _edge_parts(call)
    raw = x_j[2] - x_i[2] - z[2]
    tz = z[:2]
    return {
        "e_t": [
            (Rz.T @ (Ri @ dt - tz), "R_i is used where R_i^T belongs (transposed rotation): "
                                    "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Rz @ (Ri.T @ dt - tz), "R_ij is used where R_ij^T belongs (transposed rotation): "
                                    "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Rz @ (Ri @ dt - tz), "both rotations are transposed: e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Ri.T @ dt - tz, "the outer R_ij^T is missing: e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (-ref["e_t"], "e_t has the opposite sign: e = (pose j seen from pose i) - z_ij"),
            (_rot(x_j[2]).T @ dt - tz, "rotate t_j - t_i by pose i's angle: R_i^T, not R_j^T"),
            (Rz.T @ (Ri.T @ (x_i[:2] - x_j[:2]) - tz), "t_j - t_i, not t_i - t_j"),
        ],
        "e_theta": [
            (np.array(raw), "e_theta is not wrapped: wrap(theta_j - theta_i - theta_ij) to [-pi, pi), "
                            "e.g. with course.geometry.wrap_angle"),
            (np.array(raw % (2 * np.pi)), "e_theta is wrapped to [0, 2 pi); wrap to [-pi, pi): "
                                          "(angle + pi) % (2 pi) - pi"),
            (-ref["e_theta"], "e_theta has the opposite sign: wrap(theta_j - theta_i - theta_ij)"),
            (np.array(_wrap(x_j[2] - x_i[2]) - z[2]), "wrap the whole difference theta_j - theta_i - "
                                                       "theta_ij, not only theta_j - theta_i"),
        ],
    }


def _e_calls(part):
    def build():
        return [_edge_call(*edge) for edge in _edges()]

    return build


def _judge_e(part):
    hint = {"e_t": "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)",
            "e_theta": "e_theta = wrap(theta_j - theta_i - theta_ij) in [-pi, pi)"}[part]
    label = {"e_t": "e[{}]", "e_theta": "e[2]"}[part]

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=_failed)
        if failure:
            return failure
        for call, got, want in triples:
            if got["e"].shape != (3,):
                return Verdict(0.0, f"e has shape {got['e'].shape}, expected (3,) {call.where}")
            split = {"e_t": (got["e"][:2], want["e"][:2]), "e_theta": (got["e"][2], want["e"][2])}
            actual, expected = split[part]
            known = _e_mistakes(call, {"e_t": want["e"][:2], "e_theta": want["e"][2]})[part]
            text = compare(actual, expected, label, 1e-9, 1e-12, call.where, known, hint)
            if text:
                return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


def _a_mistakes(call, ref):
    x_i, x_j, z, dt, Ri, Rz = _edge_parts(call)
    A = ref["A"]
    column = Rz.T @ _drot_t(x_i[2]) @ dt
    return {"A": [
        (-A, "A has the opposite sign: A = de/dx_i, with top-left block -R_ij^T R_i^T and A[2, 2] = -1"),
        (_block(-Rz.T @ Ri, column, -1.0), "A's top-left block uses R_i instead of R_i^T (transposed "
                                           "rotation): it is -R_ij^T R_i^T"),
        (_block(-Rz @ Ri.T, column, -1.0), "A's top-left block uses R_ij instead of R_ij^T: it is -R_ij^T R_i^T"),
        (_block(-Rz @ Ri, Rz @ _drot(x_i[2]) @ dt, -1.0),
         "the rotations in A are transposed: e uses R_ij^T and R_i^T, so A = [[-R_ij^T R_i^T, "
         "R_ij^T dR_i^T/dtheta (t_j - t_i)], [0, 0, -1]]"),
        (_block(-Rz.T @ Ri.T, Rz.T @ _drot(x_i[2]) @ dt, -1.0),
         "A[0:2, 2] uses dR_i/dtheta; e has R_i^T, so use dR_i^T/dtheta = [[-sin, cos], [-cos, -sin]]"),
        (_block(-Rz.T @ Ri.T, -column, -1.0), "A[0:2, 2] has the opposite sign: "
                                              "dR^T/dtheta = [[-sin, cos], [-cos, -sin]]"),
        (_block(-Rz.T @ Ri.T, _drot_t(x_i[2]) @ dt, -1.0), "A[0:2, 2] lacks the factor R_ij^T: "
                                                           "R_ij^T dR_i^T/dtheta_i (t_j - t_i)"),
        (_block(-Rz.T @ Ri.T, np.zeros(2), -1.0), "A[0:2, 2] is zero: e_t depends on theta_i through R_i^T, "
                                                  "its derivative is R_ij^T dR_i^T/dtheta_i (t_j - t_i)"),
        (_block(-Ri.T, column, -1.0), "A's top-left block lacks R_ij^T: it is -R_ij^T R_i^T"),
        (_block(-Rz.T @ Ri.T, column, 1.0), "A[2, 2] = d e_theta / d theta_i = -1"),
    ]}


def _b_mistakes(call, ref):
    x_i, x_j, z, dt, Ri, Rz = _edge_parts(call)
    B = ref["B"]
    return {"B": [
        (-B, "B has the opposite sign: B = de/dx_j = [[R_ij^T R_i^T, 0], [0, 0, 1]]"),
        (_block(Rz.T @ Ri, np.zeros(2), 1.0), "B uses R_i instead of R_i^T (transposed rotation)"),
        (_block(Rz @ Ri.T, np.zeros(2), 1.0), "B uses R_ij instead of R_ij^T (transposed rotation)"),
        (_block(Rz @ Ri, np.zeros(2), 1.0), "the rotations in B are transposed: B's top-left block is R_ij^T R_i^T"),
        (_block(Ri.T, np.zeros(2), 1.0), "B's top-left block lacks R_ij^T: it is R_ij^T R_i^T"),
        (_block(Rz.T @ _rot(x_j[2]).T, np.zeros(2), 1.0), "B rotates by pose j's angle: the error rotates "
                                                          "t_j - t_i by R_i^T, so B's block is R_ij^T R_i^T"),
    ]}


# finite differences: the student's own e, perturbed one coordinate at a time
FD_EDGES = (0, 1, 3)  # indices into _edges()
FD_STEP = 1e-6
FD_HINTS = {
    ("A", 0): "d e / d t_i: A's top-left block is -R_ij^T R_i^T",
    ("A", 1): "d e / d t_i: A's top-left block is -R_ij^T R_i^T",
    ("A", 2): "d e / d theta_i = (R_ij^T dR_i^T/dtheta_i (t_j - t_i), -1), dR^T/dtheta = [[-sin, cos], [-cos, -sin]]",
    ("B", 0): "d e / d t_j: B's top-left block is R_ij^T R_i^T",
    ("B", 1): "d e / d t_j: B's top-left block is R_ij^T R_i^T",
    ("B", 2): "d e / d theta_j = (0, 0, 1)",
}


def _fd_calls():
    calls = []
    edges = _edges()
    for k in FD_EDGES:
        x_i, x_j, z, where = edges[k]
        calls.append(_edge_call(x_i, x_j, z, where))
        for p in range(6):
            for sign in (1.0, -1.0):
                xs = [x_i.copy(), x_j.copy()]
                xs[p // 3][p % 3] += sign * FD_STEP
                name = ("x_i", "x_j")[p // 3]
                moved = f"{name}[{p % 3}] {'+' if sign > 0 else '-'} {FD_STEP:g}"
                calls.append(_edge_call(xs[0], xs[1], z, f"{where}, {moved}"))
    return calls


def _judge_fd(ctx):
    """A and B against central differences of the student's own e (angle differences wrapped)."""
    triples, failure = call_fields(ctx, failed=_failed)
    fields = []
    for call, got, _ in triples:
        if got["e"].shape != (3,) or got["A"].shape != (3, 3) or got["B"].shape != (3, 3):
            return Verdict(0.0, f"e, A or B has the wrong shape {call.where} (see the shapes check)")
        fields.append(got)
    if failure:
        return failure
    good, messages, minus = {}, {}, set()
    per_edge = 13
    for block in range(len(FD_EDGES)):
        base = per_edge * block
        call = ctx.calls[base]
        for p in range(6):
            plus, minus_e = fields[base + 1 + 2 * p]["e"], fields[base + 2 + 2 * p]["e"]
            diff = plus - minus_e
            diff[2] = _wrap(diff[2])
            fd = diff / (2 * FD_STEP)
            name, column = ("A", "B")[p // 3], p % 3
            key = (name, column)
            if not good.get(key, True):
                continue
            good[key] = True
            jac = fields[base][name][:, column]
            if not np.all(np.isfinite(fd)):
                good[key] = False
                messages[key] = (f"your e is not finite near {call.where}, so {name}[:, {column}] cannot be "
                                 "checked by finite differences (see the e checks)")
                continue
            atol = 1e-6 * max(1.0, float(np.max(np.abs(fd))))
            if compare(jac, fd, "", 1e-6, atol) is None:
                continue
            good[key] = False
            row = int(np.argmax(np.abs(jac - fd)))
            text = (f"{name}[:, {column}] disagrees with finite differences of your e {call.where}: "
                    f"{name}[{row}, {column}] = {fmt(jac[row])}, central difference {fmt(fd[row])} "
                    f"(rtol=1e-06, atol={atol:.2g})")
            if np.all(np.isfinite(jac)) and compare(jac, -fd, "", 1e-6, atol) is None:
                minus.add(key)
                text += f": {name} is minus the derivative of your e"
            else:
                text += f": {FD_HINTS[key]}"
            messages[key] = text
    score = sum(good.values()) / len(good)
    if score == 1.0:
        return Verdict(1.0, "ok")
    for name in ("A", "B"):
        keys = [k for k in messages if k[0] == name]
        if keys and set(keys) <= minus:
            first = messages[keys[0]].split(f": {name} is minus")[0]
            for k in keys:
                del messages[k]
            messages[(name, -1)] = (f"{first}: {name} is minus the derivative of your e in every column that "
                                    f"differs; {name} must be de/dx_{'i' if name == 'A' else 'j'} of the same e")
    return Verdict(score, "; ".join(messages[k] for k in sorted(messages)))


# ---------------------------------------------------------------- assembly


@lru_cache(maxsize=None)
def _small_graph():
    """Six poses, eight edges (one from a later to an earlier pose), full information matrices."""
    from course.geometry import between

    rng = np.random.default_rng(7)
    truth = np.column_stack([rng.uniform(-3, 3, 6), rng.uniform(-3, 3, 6), _wrap(rng.uniform(-np.pi, np.pi, 6))])
    pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (0, 3), (5, 2), (1, 4)]
    ei, ej = (np.array(v) for v in zip(*pairs))
    z = between(truth[ei], truth[ej]) + rng.normal(size=(len(pairs), 3)) * (0.05, 0.05, 0.03)
    z[:, 2] = _wrap(z[:, 2])
    info = []
    for _ in pairs:
        L = rng.normal(size=(3, 3)) * (3.0, 3.0, 6.0)
        info.append(L @ L.T + np.diag((2.0, 2.0, 5.0)))
    poses = truth + rng.normal(size=truth.shape) * (0.1, 0.1, 0.05)
    poses[:, 2] = _wrap(poses[:, 2])
    poses_b = poses + rng.normal(size=truth.shape) * (0.1, 0.1, 0.05)
    poses_b[:, 2] = _wrap(poses_b[:, 2])
    return {"poses": poses, "edges_i": ei, "edges_j": ej, "measurements": z,
            "information": np.array(info), "fixed": np.array([0]), "poses_b": poses_b}


def _graph_at(poses, fixed):
    g = _small_graph()
    return {"poses": poses, "edges_i": g["edges_i"], "edges_j": g["edges_j"], "measurements": g["measurements"],
            "information": g["information"], "fixed": np.array(fixed, dtype=np.int64)}


def _blocks(graph):
    """Reference (e, A, B) of every edge, stacked."""
    edge = _solutions("pose_graph_edge").edge_error_and_jacobians
    out = [edge(graph["poses"][i], graph["poses"][j], z)
           for i, j, z in zip(graph["edges_i"], graph["edges_j"], graph["measurements"])]
    return tuple(np.array([o[k] for o in out]) for k in range(3))


def _assembly_calls():
    g = _small_graph()
    calls = []
    for poses, fixed, what in ((g["poses"], [0], "first pose fixed"), (g["poses"], [0, 3], "poses 0 and 3 fixed"),
                               (g["poses_b"], [0], "first pose fixed, other poses")):
        graph = _graph_at(poses, fixed)
        args = (graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"], graph["information"],
                graph["fixed"], _blocks(graph))
        calls.append(Call("@autograder.tasks:assemble_with_reference_edges", args, returns="dict",
                          label="pose_graph_assembly.assemble_normal_equations",
                          where=f"on a 6-pose, 8-edge graph ({what}; edge 7 goes from pose 5 to pose 2)"))
    return calls


def _assemble(call, *, offdiag="right", information=True, b_sign=1.0, b_swap=False, fix="right",
              outer=False, chi2_scale=1.0):
    """H, b, chi2 assembled here from the reference blocks, with one mistake or none."""
    poses, ei, ej, _, info, fixed, (E, A, B) = call.args
    n = 3 * len(poses)
    H, b, chi2 = np.zeros((n, n)), np.zeros(n), 0.0
    for k, (i, j) in enumerate(zip(ei, ej)):
        om = info[k] if information else np.eye(3)
        a, bb, e = A[k], B[k], E[k]
        si, sj = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
        if outer:
            H[si, si] += a @ om @ a.T
            H[sj, sj] += bb @ om @ bb.T
        else:
            H[si, si] += a.T @ om @ a
            H[sj, sj] += bb.T @ om @ bb
        ij, ji = a.T @ om @ bb, bb.T @ om @ a
        if offdiag == "right":
            H[si, sj] += ij
            H[sj, si] += ji
        elif offdiag == "swapped":
            H[si, sj] += ji
            H[sj, si] += ij
        elif offdiag == "ij_only":
            H[si, sj] += ij
        elif offdiag == "ji_only":
            H[sj, si] += ji
        elif offdiag == "ij_twice":  # the i,j line's block also put at [j, i]
            H[sj, si] += ij + ji
        gi, gj = a.T @ om @ e, bb.T @ om @ e
        if b_swap:
            gi, gj = gj, gi
        b[si] += b_sign * gi
        b[sj] += b_sign * gj
        chi2 += chi2_scale * float(e @ om @ e)
    held = {"right": fixed, "none": [], "first": [0]}.get(fix, fixed)
    for k in held:
        sk = slice(3 * k, 3 * k + 3)
        H[sk, :] = 0.0
        if fix != "rows":
            H[:, sk] = 0.0
        H[sk, sk] = 0.0 if fix == "no_identity" else np.eye(3)
        if fix != "b_kept":
            b[sk] = 0.0
    return H, b, chi2


def _fixed_dofs(call):
    fixed = call.args[5]
    mask = np.zeros(3 * len(call.args[0]), dtype=bool)
    for k in fixed:
        mask[3 * k:3 * k + 3] = True
    return mask


def _masks(call):
    """(free-free entries of H, fixed rows/columns of H, free entries of b, fixed entries of b)."""
    fd = _fixed_dofs(call)
    free_h = np.outer(~fd, ~fd)
    return free_h, ~free_h, ~fd, fd


def _as_array(x):
    return np.asarray(x, dtype=float)


def _shape_problem(got, n, call):
    H, b = _as_array(got["H"]), _as_array(got["b"])
    if H.shape != (n, n):
        return f"H has shape {H.shape}, expected ({n}, {n}) (3 rows and columns per pose) {call.where}"
    if b.shape != (n,):
        return f"b has shape {b.shape}, expected ({n},) {call.where}"
    if _as_array(got["chi2"]).size != 1:
        return f"chi2 has shape {_as_array(got['chi2']).shape}, expected a number {call.where}"
    return None


H_MISTAKES = (
    ({"offdiag": "swapped"}, "the off-diagonal blocks are swapped: H[i,j] += A^T Omega B (rows of pose i, "
                             "columns of pose j) and H[j,i] += B^T Omega A"),
    ({"offdiag": "ij_only"}, "H[j,i] is missing: add B^T Omega A at rows of pose j, columns of pose i "
                             "(H is symmetric)"),
    ({"offdiag": "ji_only"}, "H[i,j] is missing: add A^T Omega B at rows of pose i, columns of pose j "
                             "(H is symmetric)"),
    ({"offdiag": "ij_twice"}, "the block A^T Omega B is added at [j,i] instead of [i,j]: H[i,j] is rows "
                              "3i:3i+3, columns 3j:3j+3"),
    ({"offdiag": "none"}, "the off-diagonal blocks H[i,j] += A^T Omega B and H[j,i] += B^T Omega A are missing"),
    ({"information": False}, "the information matrix is missing: H[i,i] += A^T Omega A, "
                             "H[i,j] += A^T Omega B, ... with Omega = information[k]"),
    ({"outer": True}, "the diagonal blocks are A^T Omega A and B^T Omega B, not A Omega A^T"),
)
B_MISTAKES = (
    ({"b_sign": -1.0}, "b has the opposite sign: b[i] += A^T Omega e, b[j] += B^T Omega e "
                       "(the step then solves H dx = -b)"),
    ({"information": False}, "the information matrix is missing: b[i] += A^T Omega e"),
    ({"b_swap": True}, "b[i] takes A^T Omega e (A = de/dx_i) and b[j] takes B^T Omega e"),
)
CHI2_MISTAKES = (
    ({"information": False}, "chi2 = sum e^T Omega e: the information matrix is missing"),
    ({"chi2_scale": 0.5}, "chi2 = sum e^T Omega e, without a factor 1/2"),
)


def _judge_assembly(part):
    """``part``: "H" (free-free blocks), "b" (b and chi2 of free poses), "fixed" (fixed rows, columns, b)."""

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=_failed)
        if failure:
            return failure
        for call, got, want in triples:
            n = 3 * len(call.args[0])
            problem = _shape_problem(got, n, call)
            if problem:
                return Verdict(0.0, problem)
            H, b, chi2 = _as_array(got["H"]), _as_array(got["b"]), _as_array(got["chi2"]).reshape(())
            free_h, fixed_h, free_b, fixed_b = _masks(call)
            scale_h = float(np.max(np.abs(want["H"])))
            scale_b = float(np.max(np.abs(want["b"])))
            if part == "H":
                mask = free_h
                known = [(np.where(mask, _assemble(call, **kw)[0], 0.0), why) for kw, why in H_MISTAKES]
                text = compare(np.where(mask, H, 0.0), np.where(mask, want["H"], 0.0), "H[{}]", 1e-9,
                               1e-10 * scale_h, call.where, known,
                               "H[i,i] += A^T Omega A, H[i,j] += A^T Omega B, H[j,i] += B^T Omega A, "
                               "H[j,j] += B^T Omega B over all edges")
                if text:
                    return Verdict(0.0, text)
            elif part == "b":
                known = [(np.where(free_b, _assemble(call, **kw)[1], 0.0), why) for kw, why in B_MISTAKES]
                text = compare(np.where(free_b, b, 0.0), np.where(free_b, want["b"], 0.0), "b[{}]", 1e-9,
                               1e-10 * scale_b, call.where, known, "b[i] += A^T Omega e, b[j] += B^T Omega e")
                if text:
                    return Verdict(0.0, text)
                known = [(np.array(_assemble(call, **kw)[2]), why) for kw, why in CHI2_MISTAKES]
                text = compare(chi2, want["chi2"], "chi2", 1e-9, 0.0, call.where, known, "chi2 = sum e^T Omega e")
                if text:
                    return Verdict(0.0, text)
            else:
                fixed = [int(k) for k in call.args[5]]
                why_none = (f"pose{'s' if len(fixed) > 1 else ''} {', '.join(map(str, fixed))} "
                            f"{'are' if len(fixed) > 1 else 'is'} not held fixed: zero the rows and columns of "
                            "H and the entries of b of every pose in `fixed`, with the identity on its diagonal block")
                mistakes = [({"fix": "none"}, why_none),
                            ({"fix": "rows"}, "the columns of the fixed poses must be zeroed too (H stays symmetric)"),
                            ({"fix": "no_identity"}, "put the identity on the diagonal block of a fixed pose "
                                                     "(else H is singular)"),
                            ({"fix": "b_kept"}, "zero b at the fixed poses too (their step must be 0)")]
                if fixed != [0]:
                    mistakes.insert(1, ({"fix": "first"}, f"only pose 0 is held fixed: hold every pose in `fixed` "
                                                          f"(here {fixed})"))
                for name, actual, expected, mask, index, scale in (
                        ("H", H, want["H"], fixed_h, "H[{}]", scale_h), ("b", b, want["b"], fixed_b, "b[{}]", scale_b)):
                    slot = 0 if name == "H" else 1
                    known = [(np.where(mask, _assemble(call, **kw)[slot], 0.0), why) for kw, why in mistakes]
                    text = compare(np.where(mask, actual, 0.0), np.where(mask, expected, 0.0), index, 1e-9,
                                   1e-10 * scale, f"{call.where}, rows and columns of the fixed poses", known,
                                   "a fixed pose has zero rows and columns in H except an identity diagonal "
                                   "block, and zero b")
                    if text:
                        return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


# ---------------------------------------------------------------- dense and sparse solves


@lru_cache(maxsize=None)
def _systems():
    """Reference H (fixed [0]) and b of the small graph at two sets of poses, plus a damped H."""
    asm = _solutions("pose_graph_assembly").assemble_normal_equations
    g = _small_graph()
    H1, b1, _ = asm(g["poses"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], [0])
    H2, b2, _ = asm(g["poses_b"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], [0])
    H3 = H2 + np.diag(0.3 * np.diag(H2))
    b3 = np.random.default_rng(11).normal(size=len(b2)) * np.abs(b2).max()
    return (H1, b1), (H2, b2), (H3, b3)


def _dense_calls():
    (H1, b1), _, (H3, b3) = _systems()
    rng = np.random.default_rng(5)
    M = rng.normal(size=(12, 4))
    H4, b4 = M.T @ M + 0.1 * np.eye(4), rng.normal(size=4)
    return [Call("sparse_solve:dense_solve", (H, b), where=where) for H, b, where in (
        (H1, b1, "for H and b of the 6-pose graph (18 x 18)"),
        (H3, b3, "for a damped H of the 6-pose graph"),
        (H4, b4, "for a 4 x 4 symmetric positive definite H"))]


def _solve_mistakes(call, ref):
    H, b = call.args[:2]
    known = [(-ref["value"], "dx has the opposite sign: solve H dx = -b"),
             (np.linalg.solve(np.triu(H), -b), "H was treated as upper triangular: solve with the whole symmetric H"),
             (np.linalg.solve(np.diag(np.diag(H)), -b), "only the diagonal of H was used")]
    return {"value": known}


def _upper_calls():
    (H1, _), _, _ = _systems()
    return [Call("@autograder.tasks:upper_triangle", (H1, sparse), returns="dict",
                 label="sparse_solve.upper_triangle_csc",
                 where=f"for H of the 6-pose graph given as {'a scipy CSR matrix' if sparse else 'a dense array'}")
            for sparse in (False, True)]


def _judge_upper(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    from autograder.tasks import decode_text

    partial = None
    for call, got, want in triples:
        H = call.args[0]
        known = [(H, "this is the whole of H: keep its upper triangle only, diagonal included "
                     "(scipy.sparse.triu(H, format='csc'))"),
                 (np.tril(H), "this is the lower triangle: the upper triangle has row <= column (scipy.sparse.triu)"),
                 (np.triu(H, 1), "the diagonal is missing: the upper triangle includes it (triu with k=0)")]
        text = compare(got["M"], want["M"], "upper[{}]", 1e-12, 0.0, call.where, known, "the upper triangle of H")
        if text:
            return Verdict(0.0, text)
        if not got["sparse"]:
            partial = (f"the values are right but you returned a dense {decode_text(got['format'])} {call.where}: "
                       "return a scipy.sparse CSC matrix (scipy.sparse.triu(H, format='csc'))")
        elif not got["csc"]:
            partial = (f"the values are right but the matrix is in {decode_text(got['format']).upper()} format "
                       f"{call.where}: the sparse solver expects CSC (format='csc' or .tocsc())")
    return Verdict(0.5, partial) if partial else Verdict(1.0, "ok")


@lru_cache(maxsize=None)
def _pattern():
    """CSC pattern (indices, indptr) of the union of the upper triangles of the three systems,
    and each system's values on it (explicit zeros included)."""
    import scipy.sparse as sp

    systems = _systems()
    union = sum(np.abs(np.triu(H)) for H, _ in systems) > 0
    pattern = sp.csc_matrix(union.astype(float))
    pattern.sort_indices()
    rows = pattern.indices
    cols = np.repeat(np.arange(pattern.shape[1]), np.diff(pattern.indptr))
    values = [np.asarray(H[rows, cols], dtype=float) for H, _ in systems]
    return pattern.shape, pattern.indices.copy(), pattern.indptr.copy(), values


def _sparse_calls(count):
    def build():
        shape, indices, indptr, values = _pattern()
        rhs = [b for _, b in _systems()][:count]
        where = ("for the upper triangle of H of the 6-pose graph (one call)" if count == 1 else
                 f"for {count} successive calls on one solver with the same pattern and new values "
                 "(other poses, then a damped H)")
        return [Call("@autograder.tasks:sparse_solves", (shape, indices, indptr, values[:count], rhs),
                     returns="dict", label="sparse_solve.SparseCholeskySolver.solve", where=where)]

    return build


def _judge_sparse(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    systems = _systems()
    for call, got, want in triples:
        count = len(call.args[3])
        for k in range(count):
            name = f"dx{k}"
            H, b = systems[k]
            known = [(-want[name], "dx has the opposite sign: solve H dx = -b"),
                     (np.linalg.solve(np.triu(H), -b),
                      "H_upper holds only the upper triangle of H: tell the solver (qdldl.Solver(H_upper, "
                      "upper=True)), do not solve with H_upper as if it were H")]
            if k > 0:
                first = systems[0][0]
                known.insert(0, (np.linalg.solve(first, -b),
                                 "this solve used the first call's matrix: keep the symbolic analysis but "
                                 "refactorize with the new values on every later call (qdldl: "
                                 "solver.update(H_upper, upper=True)) before solving"))
                known.insert(1, (-np.linalg.solve(first, -b), "this solve used the first call's matrix and "
                                                              "has the opposite sign"))
            what = f"{call.where}, call {k + 1}" if count > 1 else call.where
            text = compare(got.get(name, np.array(np.nan)), want[name], "dx[{}]", 1e-8, 1e-10, what, known,
                           "dx solves H dx = -b")
            if text:
                return Verdict(0.0, text)
    return Verdict(1.0, "ok")


def _judge_reuse(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    _, got, _ = triples[0]
    created = float(got.get("solvers_created", np.nan))
    calls = len(ctx.calls[0].args[3])
    if not np.isfinite(created):
        return Verdict(0.0, "the grader could not count the qdldl.Solver objects your solver made")
    if created == 1:
        return Verdict(1.0, f"ok (one qdldl.Solver for {calls} solves)")
    if created == 0:
        return Verdict(0.0, f"no qdldl.Solver was made in {calls} solves: make one on the first call "
                            "(ordering and symbolic analysis) and update it on later calls")
    return Verdict(0.0, f"{int(created)} qdldl.Solver objects were made for {calls} solves with the same pattern: "
                        "make one on the first call and refactorize it with solver.update(H_upper, upper=True) "
                        "later, so that the ordering and symbolic analysis are done once")


# ---------------------------------------------------------------- Ceres cost


@lru_cache(maxsize=None)
def _ceres_inputs():
    """(measurement, U, x_i, x_j, where): full square-root information matrices U (upper, U^T U = Omega)."""
    rng = np.random.default_rng(13)
    out = []
    for k in (0, 1, 3, 5):
        x_i, x_j, z, where = _edges()[k]
        L = rng.normal(size=(3, 3)) * (4.0, 4.0, 8.0)
        omega = L @ L.T + np.diag((3.0, 3.0, 6.0))
        U = np.linalg.cholesky(omega).T
        out.append((z, U, x_i, x_j, where + ", full U"))
    return out


def _ceres_calls(task):
    def build():
        return [Call(f"@autograder.tasks:{task}", (z, U, x_i, x_j), returns="dict",
                     label="ceres_edge_cost.SE2EdgeCost" + (".evaluate" if task == "ceres_cost" else ".Evaluate"),
                     where=where) for z, U, x_i, x_j, where in _ceres_inputs()]

    return build


def _edge_reference(x_i, x_j, z):
    return _solutions("pose_graph_edge").edge_error_and_jacobians(x_i, x_j, z)


def _ceres_mistakes(call, ref):
    z, U, x_i, x_j = call.args
    e, A, B = _edge_reference(x_i, x_j, z)
    omega = U.T @ U
    raw = e.copy()
    raw[2] = x_j[2] - x_i[2] - z[2]
    return {
        "r": [(e, "r is the unwhitened error e: r = U e (sqrt_information times e), so that r^T r = e^T Omega e"),
              (omega @ e, "multiply e by the square root U, not by Omega = U^T U"),
              (U.T @ e, "r = U e, not U^T e"),
              (-U @ e, "r has the opposite sign: r = U e with e = (pose j seen from pose i) - z_ij"),
              (U @ raw, "the angle error is not wrapped to [-pi, pi)")],
        "J_i": [(A, "the Jacobian is not whitened: jacobians[0] = U A (row-major), A = de/dx_i"),
                (omega @ A, "whiten with U, not Omega: jacobians[0] = U A"),
                (U.T @ A, "jacobians[0] = U A, not U^T A"),
                ((U @ A).T, "jacobians[0] is filled column-major: Ceres reads it row-major, "
                            "jacobians[0][:] = (U @ A).ravel()"),
                (-U @ A, "jacobians[0] has the opposite sign: U de/dx_i")],
        "J_j": [(B, "the Jacobian is not whitened: jacobians[1] = U B (row-major), B = de/dx_j"),
                (omega @ B, "whiten with U, not Omega: jacobians[1] = U B"),
                (U.T @ B, "jacobians[1] = U B, not U^T B"),
                ((U @ B).T, "jacobians[1] is filled column-major: Ceres reads it row-major, "
                            "jacobians[1][:] = (U @ B).ravel()"),
                (-U @ B, "jacobians[1] has the opposite sign: U de/dx_j")],
    }


def _judge_ceres(names):
    causes = {"r": "r = U e", "J_i": "jacobians[0] = U A, row-major", "J_j": "jacobians[1] = U B, row-major"}
    labels = {"r": "residuals[{}]", "J_i": "jacobians[0] as 3x3 [{}]", "J_j": "jacobians[1] as 3x3 [{}]"}

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=_failed)
        if failure:
            return failure
        for call, got, want in triples:
            known = _ceres_mistakes(call, want)
            for name in names:
                scale = max(1.0, float(np.max(np.abs(want[name]))))
                text = compare(got[name], want[name], labels[name], 1e-9, 1e-12 * scale, call.where,
                               known[name], causes[name])
                if text:
                    return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


def _judge_partial_jacobians(ctx):
    """With jacobians None, [None, J_j] or [J_i, None], Evaluate fills what it is asked for,
    the same as when both Jacobians are requested (the values are graded by the other checks)."""
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    for call, got, _ in triples:
        both = f"{call.where}, with both jacobians requested"
        if not got["both_ok"]:
            return Verdict(0.0, f"Evaluate did not return True {both}: return True after filling the buffers")
        if np.any(np.isnan(got["both_r"])) or np.any(np.isnan(got["both_J"])) or np.any(np.isnan(got["both_J2"])):
            return Verdict(0.0, f"Evaluate left a buffer unfilled {both}: write into the buffers Ceres gives, "
                                "residuals[:] = ..., jacobians[k][:] = ... (assigning residuals = ... only rebinds "
                                "the name)")
        r = got["both_r"]
        for request, jac, what in (("none", None, "jacobians=None (residuals only)"),
                                   ("first", got["both_J2"], "jacobians=[None, J_j] (x_i constant, e.g. a fixed pose)"),
                                   ("second", got["both_J"], "jacobians=[J_i, None] (x_j constant)")):
            where = f"{call.where}, with {what}"
            if not got[f"{request}_ok"]:
                return Verdict(0.0, f"Evaluate did not return True {where}: return True after filling the buffers")
            text = compare(got[f"{request}_r"], r, "residuals[{}]", 1e-12, 1e-14, where, (),
                           "the residuals must not depend on which Jacobians are requested")
            if text:
                return Verdict(0.0, text)
            if jac is not None:
                text = compare(got[f"{request}_J"], jac, "jacobian[{}]", 1e-12, 1e-14, where, (),
                               "fill each jacobians[k] that is not None, the same as when both are requested")
                if text:
                    return Verdict(0.0, text)
    return Verdict(1.0, "ok")


# ---------------------------------------------------------------- vectorized (optional)


def _fast_graph():
    g = _small_graph()
    return _graph_at(g["poses"], [0, 3])


def _fast_edge_calls():
    return [Call("@autograder.tasks:fast_edges", (_fast_graph(),), returns="dict",
                 label="pose_graph_fast.edge_errors_and_jacobians",
                 where="on the 8 edges of the 6-pose graph")]


def _fast_edge_mistakes(call, ref):
    graph = call.args[0]
    raw = ref["e"].copy()
    raw[:, 2] = graph["poses"][graph["edges_j"], 2] - graph["poses"][graph["edges_i"], 2] - graph["measurements"][:, 2]
    return {"e": [(raw, "e[:, 2] is not wrapped to [-pi, pi)"), (-ref["e"], "e has the opposite sign")],
            "A": [(-ref["A"], "A has the opposite sign")], "B": [(-ref["B"], "B has the opposite sign")]}


def _fast_assembler_calls():
    g = _small_graph()
    graph = _fast_graph()
    blocks = [_blocks(graph), _blocks(_graph_at(g["poses_b"], [0, 3]))]
    return [Call("@autograder.tasks:fast_assemble", (graph, blocks), returns="dict",
                 label="pose_graph_fast.SparseAssembler",
                 where="on the 6-pose graph (poses 0 and 3 fixed), assemble called twice with new blocks")]


def _judge_fast_assembler(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        return failure
    call, got, want = triples[0]
    note = ""
    for k in range(2):
        where = f"{call.where} (call {k + 1})"
        H_ref = want[f"H{k}"]
        full = H_ref + np.triu(H_ref, 1).T
        known = [(full, "H holds the whole matrix: store the upper triangle only (diagonal included)"),
                 (np.tril(full), "H holds the lower triangle: store the upper triangle (row <= column)")]
        if k == 1:
            known.append((H_ref + want["H0"], "the second call added onto the first call's values: "
                                              "start every assemble from zero"))
        scale = float(np.max(np.abs(H_ref)))
        for name, label, extra in ((f"H{k}", "H[{}]", known), (f"b{k}", "b[{}]",
                                                              [(-want[f"b{k}"], "b has the opposite sign")]),
                                   (f"chi2{k}", "chi2", [])):
            atol = 1e-10 * (scale if name.startswith("H") else max(1.0, float(np.max(np.abs(want[name])))))
            text = compare(got[name], want[name], label, 1e-9, atol, where, extra,
                           "the same H (upper triangle), b and chi2 as the per-edge loop")
            if text:
                return Verdict(0.0, text)
        if not got[f"csc{k}"]:
            return Verdict(0.5, f"the values are right but H is not a scipy.sparse CSC matrix {where}")
    if not np.isfinite(got["diagonal_ok"]):
        note = (" (note: PoseGraphProblem also reads SparseAssembler.diagonal_positions, the positions of the "
                "diagonal entries in H.data, to add damping; yours has none)")
    elif not got["diagonal_ok"]:
        note = " (note: diagonal_positions does not point at the diagonal entries of H.data)"
    return Verdict(1.0, "ok" + note)


# ---------------------------------------------------------------- end to end


@lru_cache(maxsize=None)
def _e2e_graph():
    from course.datasets import manhattan

    g = manhattan(40, seed=2)
    return {"poses": g.poses, "edges_i": g.edges_i, "edges_j": g.edges_j, "measurements": g.measurements,
            "information": g.information, "fixed": g.fixed, "name": g.name}


def _end_calls():
    return [Call("@autograder.tasks:minimize_pose_graph", (_e2e_graph(), "gauss-newton"), {"vectorized": False},
                 returns="dict", label="minimize(pose graph, 'gauss-newton') with your pose_graph_edge, "
                                       "pose_graph_assembly and sparse_solve")]


def _judge_end(ctx):
    triples, failure = call_fields(ctx, failed=_failed)
    if failure:
        if "SIGSEGV" in failure.message:
            failure.message += (": the sparse solver (qdldl) crashes when the matrix it is given is not the upper "
                                "triangle of a symmetric H; see the upper_triangle_csc and SparseCholeskySolver checks")
        return failure
    _, got, want = triples[0]
    graph = _e2e_graph()
    text = compare(got["final_chi2"], want["final_chi2"], "final chi2", 1e-6, 0.0)
    moved = float(np.max(np.abs(got["params"] - want["params"])))
    if text is None:
        return Verdict(1.0, f"ok (chi2 {float(got['final_chi2']):.6g} after {int(got['iterations'])} iterations)")
    return Verdict(0.0, (
        f"Gauss-Newton on {graph['name']} ({len(graph['poses'])} poses, {len(graph['edges_i'])} edges) ends at chi2 "
        f"{fmt(got['final_chi2'])} after {int(got['iterations'])} iterations; the reference ends at "
        f"{fmt(want['final_chi2'])} after {int(want['iterations'])} (rtol 1e-6; poses differ by up to {moved:.3g}). "
        "This run uses your pose_graph_edge, pose_graph_assembly and sparse_solve; their unit checks say "
        "which part differs"))


# ---------------------------------------------------------------- registry


def _check(exercise, title, points, calls, judge, **kwargs):
    return Check(f"{exercise}: {title}", exercise, points, calls, judge, **kwargs)


CHECKS = [
    _check(EDGE, "shapes", 1, _edge_calls, _judge_edge_shapes),
    _check(EDGE, "e_t (translation error)", 2, _e_calls("e_t"), _judge_e("e_t")),
    _check(EDGE, "e_theta wrapped to [-pi, pi)", 2, _e_calls("e_theta"), _judge_e("e_theta")),
    _check(EDGE, "A values", 3, _edge_calls,
           _values(("A",), 1e-9, 1e-12, _a_mistakes,
                  "A = [[-R_ij^T R_i^T, R_ij^T dR_i^T/dtheta_i (t_j - t_i)], [0, 0, -1]]")),
    _check(EDGE, "B values", 2, _edge_calls,
           _values(("B",), 1e-9, 1e-12, _b_mistakes, "B = [[R_ij^T R_i^T, 0], [0, 0, 1]]")),
    _check(EDGE, "A, B vs finite differences of e", 2, _fd_calls, _judge_fd),
    _check(ASSEMBLY, "H blocks of the free poses", 3, _assembly_calls, _judge_assembly("H")),
    _check(ASSEMBLY, "b and chi2", 2, _assembly_calls, _judge_assembly("b")),
    _check(ASSEMBLY, "fixed poses (first pose, and poses 0 and 3)", 2, _assembly_calls, _judge_assembly("fixed")),
    _check(DENSE, "dx solves H dx = -b", 2, _dense_calls,
           _values(("value",), 1e-8, 1e-10, _solve_mistakes, "dx solves H dx = -b", labels={"value": "dx"},
                  errors={"LinAlgError": "H is symmetric positive definite here"})),
    _check(UPPER, "upper triangle as CSC", 1, _upper_calls, _judge_upper),
    _check(SPARSE, "first solve", 2, _sparse_calls(1), _judge_sparse),
    _check(SPARSE, "later solves with new values, same pattern", 2, _sparse_calls(3), _judge_sparse),
    _check(SPARSE, "one symbolic analysis for the pattern", 1, _sparse_calls(3), _judge_reuse),
    _check(CERES, "residuals r = U e", 2, _ceres_calls("ceres_cost"), _judge_ceres(("r",))),
    _check(CERES, "jacobians U A, U B", 3, _ceres_calls("ceres_cost"), _judge_ceres(("J_i", "J_j"))),
    _check(CERES, "jacobians None or one block constant", 1, _ceres_calls("ceres_partial_jacobians"),
           _judge_partial_jacobians),
    _check(FAST_EDGES, "e, A, B of all edges (optional)", 1, _fast_edge_calls,
           _values(("e", "A", "B"), 1e-9, 1e-12, _fast_edge_mistakes,
                  "the same e, A, B as pose_graph_edge, edge by edge")),
    _check(FAST_ASSEMBLER, "H (upper, CSC), b, chi2 (optional)", 1, _fast_assembler_calls, _judge_fast_assembler),
    _check(END, "gauss-newton", 3, _end_calls, _judge_end),
]
