"""What the check modules from chapter 2 on share: a check named after its exercise
(:func:`check`), the judges' failure with every TODO named (:func:`failed`, :func:`values`)
and angles wrapped to [-pi, pi) (:func:`wrap`), judged by what makes them right
(:func:`same_angle`)."""

import numpy as np

from autograder.checks import Check, Verdict
from autograder.feedback import TODO_PATTERN, call_fields, compare, fields_of, first_error
from autograder.feedback import values as _feedback_values

#: what a vectorized task adds to a stub's message when the per-edge loop would stand in
#: for it (``autograder.tasks.pose_graph_fast``)
LOOP_NOTE = "[the per-edge loop works]"


def wrap(angle):
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


#: how far (radians) an angle may be from the reference's modulo 2 pi and be the same angle
SAME_ANGLE_ATOL = 1e-12


def same_angle(actual, expected, atol=SAME_ANGLE_ATOL):
    """Where ``actual`` is as right as the reference's wrapped angle ``expected`` (elementwise): finite,
    in the contract's range taken closed, ``[-pi, pi]``, and equal to ``expected`` modulo 2 pi. At the
    range's open end the answer is not unique: ``arctan2(sin, cos)`` gives +pi where ``(a + pi) % (2 pi)
    - pi`` gives -pi, the same angle with the same cost and Jacobians, and both keep full marks; an
    angle not wrapped, or off by 2 pi, is outside the range and is not."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(actual) & (np.abs(actual) <= np.pi) & (np.abs(wrap(actual - expected)) <= atol)


def angles_as_reference(column):
    """``values``' ``equivalent`` for an output whose ``[..., column]`` is a wrapped angle: those entries
    that are the reference's angle (:func:`same_angle`) read as the reference's."""

    def equivalent(got, want, call):
        got, want = np.array(got, dtype=float), np.asarray(want, dtype=float)
        if got.shape != want.shape or got.ndim == 0:
            return got
        same = same_angle(got[..., column], want[..., column])
        got[..., column] = np.where(same, want[..., column], got[..., column])
        return got

    return equivalent


def failed(ctx, hints=None):
    """``first_error`` naming every TODO stub met (a constructor stub hides its methods')."""
    verdict = first_error(ctx, hints)
    if verdict is None or not verdict.not_implemented:
        return verdict
    names, loop = list(verdict.not_implemented), False
    for outcome in ctx.student:
        if outcome.error is not None:
            loop = loop or LOOP_NOTE in outcome.error.message
            for name in TODO_PATTERN.findall(outcome.error.message):
                if name not in names:
                    names.append(name)
    message = verdict.message
    if loop:
        message += (" (optional, going further: without it PoseGraphProblem falls back to your "
                    "per-edge loop pose_graph_assembly, fine for small graphs)")
    return Verdict(0.0, message, tuple(names))


def values(*args, **kwargs):
    """``autograder.feedback.values``, naming every TODO stub met (see :func:`failed`)."""
    judge = _feedback_values(*args, **kwargs)

    def wrapped(ctx):
        return failed(ctx, kwargs.get("errors")) or judge(ctx)

    return wrapped


def check(exercise, title, points, calls, judge, **kwargs):
    return Check(f"{exercise}: {title}", exercise, points, calls, judge, **kwargs)


def assembler_judge(cause: str, owner: str):
    """The judge of a sparse assembler called twice (``autograder.tasks.common.assemble_each``):
    H (upper triangle, ``atol`` 1e-10 of its largest entry), b and chi2 of each call against the
    reference, then half the points when H is not CSC, and a note on ``diagonal_positions``
    (read by ``owner``, the problem that adds damping there)."""

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        call, got, want = triples[0]
        known = ctx.known(0)
        for k in range(2):
            where = f"{call.where} (call {k + 1})"
            scale = float(np.max(np.abs(want[f"H{k}"])))
            for name, label in ((f"H{k}", "H[{}]"), (f"b{k}", "b[{}]"), (f"chi2{k}", "chi2")):
                atol = 1e-10 * (scale if name.startswith("H") else max(1.0, float(np.max(np.abs(want[name])))))
                text = compare(got[name], want[name], label, 1e-9, atol, where, known.get(name, ()), cause)
                if text:
                    return Verdict(0.0, text)
            if not got[f"csc{k}"]:
                return Verdict(0.5, f"the values are right but H is not a scipy.sparse CSC matrix {where}")
        note = ""
        if not np.isfinite(got["diagonal_ok"]):
            note = (f" (note: {owner} also reads diagonal_positions, the positions of the diagonal entries in "
                    "H.data, to add damping; yours has none)")
        elif not got["diagonal_ok"]:
            note = " (note: diagonal_positions does not point at the diagonal entries of H.data)"
        return Verdict(1.0, "ok" + note)

    return judge


def residual_or_jacobian(name: str, blocks, judge, differences, residual: str, residual_check: str, model: str):
    """``judge`` of the Jacobian ``name``; when it finds the student's Jacobian wrong, the feedback
    also says whether it agrees with central differences of the student's own ``residual`` (the
    ``model`` is wrong, not the derivative) or not (the derivative is wrong), and which blocks
    differ from the reference.

    ``blocks``: ``(text, index)`` pairs, ``got[index]`` a block of the Jacobian; ``differences(ctx,
    name)``: the central differences of the student's residual, shaped like the Jacobian, or None
    when a call failed; call 0 is the one judged; ``residual_check`` names the residual's check.
    """

    def judged(ctx):
        verdict = judge(ctx)
        if verdict.fraction >= 1.0 or verdict.not_implemented or ctx.student[0].error is not None:
            return verdict
        student, bad = fields_of(ctx.student[0], ctx.calls[0])
        reference, _ = fields_of(ctx.reference[0], ctx.calls[0])
        if bad:
            return verdict
        got, want, fd = student.get(name), reference.get(name), differences(ctx, name)
        if got is None or want is None or fd is None or np.shape(got) != np.shape(want) or fd.shape != np.shape(got):
            return verdict
        got, want = np.asarray(got, float), np.asarray(want, float)
        scale = max(1.0, float(np.max(np.abs(want))))
        differ = [text for text, index in blocks
                  if not np.allclose(got[index], want[index], rtol=1e-6, atol=1e-8 * scale)]
        where = f" ({'; '.join(differ)} differ from the reference)" if differ else ""
        r_want = np.asarray(reference[residual], float)
        r_got = np.asarray(student.get(residual, np.nan), float)
        r_right = r_got.shape == r_want.shape and np.allclose(r_got, r_want, rtol=1e-8,
                                                              atol=1e-10 * max(1.0, float(np.max(np.abs(r_want)))))
        gap = np.abs(got - fd) - 1e-4 * (np.abs(fd) + scale)
        if not np.isfinite(gap).all() or (gap > 0).any():
            worst = np.argwhere(~np.isfinite(gap))[0] if not np.isfinite(gap).all() else np.unravel_index(
                int(np.argmax(gap)), gap.shape)
            index = tuple(int(k) for k in worst)
            said = (f"\nResidual or Jacobian: your {name} does not agree with central differences of your own "
                    f"{residual} either ({name}{list(index)} = {got[index]:.6g}, your {residual}'s differences give "
                    f"{fd[index]:.6g}): the derivative is wrong{where}"
                    + (f"; your {residual} is right." if r_right else
                       f"; your {residual} is wrong too (see {residual_check})."))
        else:
            said = (f"\nResidual or Jacobian: your {name} agrees with central differences of your own {residual}"
                    f"{where}: the derivative is right for the {residual} you compute, so the {model} itself is "
                    f"wrong: fix {residual} first ({residual_check}), then the Jacobians that follow from it.")
        return Verdict(verdict.fraction, verdict.message + said, verdict.not_implemented)

    return judged
