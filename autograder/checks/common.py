"""What the check modules from chapter 2 on share: a check named after its exercise
(:func:`check`), the judges' failure with every TODO named (:func:`failed`, :func:`values`)
and angles wrapped to [-pi, pi) (:func:`wrap`)."""

import numpy as np

from autograder.checks import Check, Verdict
from autograder.feedback import TODO_PATTERN, first_error
from autograder.feedback import values as _feedback_values

#: what a vectorized task adds to a stub's message when the per-edge loop would stand in
#: for it (``autograder.tasks.pose_graph_fast``)
LOOP_NOTE = "[the per-edge loop works]"


def wrap(angle):
    return (np.asarray(angle, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


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
