"""Tolerance comparisons that produce feedback a student can act on.

Every comparison is ``|actual - expected| <= atol + rtol |expected|`` elementwise
(``numpy.testing.assert_allclose``'s rule) with an explicit rtol and atol. A failed
comparison names the entry, the expected and the actual value and, when the output
matches a known mistake (its output on the same inputs, from the instructor's catalogue,
shipped as data for the public checks), its likely cause.
"""

import re

import numpy as np

from autograder.records import Verdict

#: a TODO name in a stub's NotImplementedError message
TODO_PATTERN = re.compile(r"TODO ([A-Za-z_][\w.]*)")


def fmt(x) -> str:
    """A number or a short vector for feedback."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 0:
        return f"{float(arr):.6g}"
    if arr.size <= 6:
        return "(" + ", ".join(f"{v:.6g}" for v in arr.ravel()) + ")"
    return f"array of shape {arr.shape}"


def not_implemented_name(error, call=None):
    """The TODO name when ``error`` is the stub's NotImplementedError, else None."""
    if error is None or error.kind != "NotImplementedError":
        return None
    match = TODO_PATTERN.search(error.message)
    if match:
        return match.group(1)
    if call is not None and not call.target.startswith("@"):
        return call.function
    return "?"


def describe_error(error, call=None) -> str:
    """One line about a call that failed."""
    function = call.function if call is not None else "your code"
    where = f" ({error.where})" if error.where else ""
    todo = not_implemented_name(error, call)
    if todo:
        if todo == "?":
            return f"not implemented: NotImplementedError while running {function}{where}"
        return f"TODO {todo}: not implemented"
    if error.kind == "SystemExit":
        return f"{function} {error.message}{where}: return the result instead of exiting"
    if error.kind == "MemoryError":
        return (f"{function} ran out of memory (MemoryError{': ' + error.message if error.message else ''})"
                f"{where}: the grader allows about 2 GiB; do not build m x m matrices or huge arrays")
    if error.kind == "Timeout":
        return f"{function} {error.message}"
    if error.kind == "Crash":
        return f"the process running {function} {error.message}"
    if error.kind == "ImportFailure":
        return f"{error.message}{where}"
    if error.kind == "OutputError":
        return f"{function} {error.message}"
    inputs = f" {call.where}" if call is not None and call.where else ""  # which inputs it fails on
    return f"{function}{inputs} raised {error.kind}: {error.message}{where}"


def first_error(ctx, hints=None):
    """A zero Verdict for the first call of the check that failed in the child, or None.

    ``hints`` maps an exception type name to a likely cause appended to the message.
    Calls whose result was lost because a later call hung or crashed come last.
    """
    failed = [(call, o.error) for call, o in zip(ctx.calls, ctx.student) if o.error is not None]
    failed.sort(key=lambda pair: pair[1].kind == "Lost")
    if not failed:
        return None
    call, error = failed[0]
    todo = not_implemented_name(error, call)
    message = describe_error(error, call)
    if hints and error.kind in hints:
        message += f": {hints[error.kind]}"
    return Verdict(0.0, message, (todo,) if todo and todo != "?" else ())


def modified_in_place(ctx):
    """A zero Verdict for the first call that changed one of its arguments, or None.

    Every call gets its own copy of the inputs, so the values it returns can be right;
    but the loop reuses its arrays after the call (H after a rejected step, b, the poses),
    so writing into them breaks the solver later, far from the cause.
    """
    for call, outcome in zip(ctx.calls, ctx.student):
        if outcome.error is None and outcome.modified:
            names = ", ".join(outcome.modified)
            plural = "s" if len(outcome.modified) > 1 else ""
            at = f" {call.where}" if call.where else ""
            return Verdict(0.0, (
                f"{call.function} modified its argument{plural} {names} in place{at}: work on a copy "
                "(H = H + np.diag(d), not H += ...; x = x.copy() before writing into it); the "
                "framework reuses its arrays after the call"))
    return None


def _kind_text(kind: str) -> str:
    if kind.startswith("tuple:"):
        return f"a tuple of {kind.split(':')[1]} values"
    if kind.startswith("dataclass:"):
        return f"a {kind.split(':')[1]}"
    return {"value": "a single array or number", "dict": "a dict"}.get(kind, kind or "nothing")


def fields_of(outcome, call):
    """``(fields, None)`` named as ``call.returns`` says, or ``(None, message)``."""
    returns = call.returns
    raw = outcome.fields
    if isinstance(returns, tuple):
        if outcome.kind != f"tuple:{len(returns)}":
            return None, (f"{call.function} returned {_kind_text(outcome.kind)}, expected a tuple "
                          f"({', '.join(returns)})")
        return {name: raw[str(k)] for k, name in enumerate(returns)}, None
    if returns == "state":
        if not outcome.kind.startswith("dataclass:") or not {"lam", "nu"} <= set(raw):
            return None, (f"{call.function} returned {_kind_text(outcome.kind)}, expected a "
                          "DampingState(lam, nu) (from course.solver.damping)")
        return {"lam": raw["lam"], "nu": raw["nu"]}, None
    if returns == "dict":
        return dict(raw), None
    if outcome.kind != "value":
        return None, f"{call.function} returned {_kind_text(outcome.kind)}, expected one array or number"
    return {"value": raw["value"]}, None


def call_fields(ctx, hints=None, failed=first_error):
    """The student's and the reference's fields of each call, for a judge to compare.

    Returns ``(triples, failure)``. ``failure`` is the first reason to give no credit
    before comparing values, as a zero Verdict, or None: a call that failed in the child
    (``failed(ctx, hints)``, :func:`first_error` unless a chapter has its own), then, in
    call order, an output ``fields_of`` cannot read or a framework task's dict with other
    keys than the reference's. ``triples`` holds ``(call, got, want)`` for every call
    before that failure (none when a call failed in the child).

    A judge that reports the first difference in call order compares the triples, then
    ends with ``return failure or Verdict(1.0, "ok")``; one that needs every call returns
    ``failure`` before looking at them.
    """
    failure = failed(ctx, hints) or modified_in_place(ctx)
    if failure:
        return [], failure
    triples = []
    for call, student, reference in zip(ctx.calls, ctx.student, ctx.reference):
        got, problem = fields_of(student, call)
        if problem:
            return triples, Verdict(0.0, problem)
        want, _ = fields_of(reference, call)
        if call.returns == "dict" and set(got) != set(want):
            return triples, Verdict(0.0, "the run returned malformed results")
        triples.append((call, got, want))
    return triples, None


def close(actual, expected, rtol, atol, same_non_finite=False) -> bool:
    """``|actual - expected| <= atol + rtol |expected|`` everywhere; with ``same_non_finite`` an entry
    that is the same infinity, or nan, in both counts as close (a slip that gives inf or nan there)."""
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    if actual.shape != expected.shape:
        return False
    with np.errstate(invalid="ignore", over="ignore"):
        near = np.abs(actual - expected) <= atol + rtol * np.abs(expected)
    if same_non_finite:
        near |= (actual == expected) | (np.isnan(actual) & np.isnan(expected))
    return bool(np.all(near))


def compare(actual, expected, name, rtol, atol, where="", mistakes=(), cause="", scalar=False, groups=None):
    """``None`` when ``actual`` matches ``expected``; otherwise the feedback line.

    ``mistakes``: ``(value, text)`` pairs, the outputs of known wrong formulas on the
    same inputs; the first that matches ``actual`` gives the likely cause, else ``cause``.
    ``scalar``: a size-1 array is accepted for a number. ``groups``: kinds of rows (the
    first axis), ``{text: row indices}`` (``Call.groups``): when only some rows go wrong, the
    line says which, and which kinds they are.
    """
    actual = np.asarray(actual, dtype=float)
    expected = np.asarray(expected, dtype=float)
    at = f" {where}" if where else ""
    pattern = name
    if "{}" in pattern:
        name = pattern.replace("{}", ":")

    def entry(index):
        if "{}" in pattern:
            return pattern.replace("{}", ", ".join(map(str, index)))
        return f"{name}{_index(index)}"

    if scalar and actual.size == 1 and expected.ndim == 0:
        actual = actual.reshape(())
    if actual.shape != expected.shape:
        shape = "a number" if expected.ndim == 0 else str(expected.shape)
        text = f"{name} has shape {actual.shape}, expected {shape}{at}"
        if actual.ndim == 2 and actual.shape[::-1] == expected.shape:
            text += f": {name} is transposed"
        elif actual.size == expected.size:
            text += ": same numbers, wrong shape (flatten or reshape it)"
        for value, why in mistakes:  # a known slip may give another length (a loop that stops elsewhere)
            if np.shape(value) == actual.shape and close(actual, value, rtol, atol):
                return f"{text}: {why}"
        return text
    finite = np.isfinite(actual)
    if not finite.all():  # the first entry that is not a number, with the slip or the cause as for any other
        index = tuple(int(k) for k in np.argwhere(~finite)[0])
        text = (f"{entry(index)} = {actual[index]} (not a finite number), expected "
                f"{fmt(expected[index])}{at}{which_rows(~finite, groups or {})}")
        for value, why in mistakes:
            if np.shape(value) == actual.shape and close(actual, value, rtol, atol, same_non_finite=True):
                return f"{text}: {why}"
        return f"{text}: {cause}" if cause else text
    excess = np.abs(actual - expected) - (atol + rtol * np.abs(expected))
    bad = excess > 0
    if not bad.any():
        return None
    index = tuple(int(k) for k in np.unravel_index(int(np.argmax(excess)), excess.shape)) if excess.ndim else ()
    got_text, want_text = fmt(actual[index]), fmt(expected[index])
    if got_text == want_text:  # print enough digits to see the difference, and how large it is
        got_text, want_text = f"{float(actual[index]):.17g}", f"{float(expected[index]):.17g}"
    text = f"{entry(index)} = {got_text}, expected {want_text}{at}"
    if expected.ndim:
        text += f" ({int(bad.sum())} of {bad.size} entries differ; rtol={rtol:g}, atol={atol:g})"
        text += which_rows(bad, groups or {})
    else:
        text += f" (rtol={rtol:g}, atol={atol:g})"
    for value, why in mistakes:
        if close(actual, value, rtol, atol):
            return f"{text}: {why}"
    relative = _relative_error(actual, expected)
    if 1e-8 < relative < 1e-5:
        text += (f"; relative error {relative:.1e}, about float32's precision: compute in float64 "
                 "(np.float32 or dtype=np.float32 somewhere?)")
    return f"{text}: {cause}" if cause else text


def which_rows(bad, groups) -> str:
    """What to say of the rows (first axis) of ``bad`` (a mask of the wrong entries) that go wrong:
    nothing when all or none do, else their indices and the kinds of ``groups`` they are."""
    if bad.ndim == 0 or len(bad) < 2:
        return ""
    rows = np.flatnonzero(bad.reshape(len(bad), -1).any(axis=1))
    if len(rows) in (0, len(bad)):
        return ""
    shown = ", ".join(str(k) for k in rows[:8]) + (", ..." if len(rows) > 8 else "")
    text = f"; only row{'s' if len(rows) > 1 else ''} {shown} of {len(bad)} go{'' if len(rows) > 1 else 'es'} wrong"
    wrong = set(int(k) for k in rows)
    kinds = [(label, {int(k) for k in members}) for label, members in groups.items()]
    kinds = [(label, members) for label, members in kinds if members and max(members) < len(bad)]
    exact = [label for label, members in kinds if members == wrong]
    within = [label for label, members in kinds if wrong < members]
    if exact:
        text += f": exactly the one{'s' if len(wrong) > 1 else ''} {exact[0]}"
    elif within:
        text += f", all of them among those {within[0]}"
    else:
        touched = [f"{len(wrong & members)} of the {len(members)} rows {label}" for label, members in kinds
                   if wrong & members]
        if touched:
            text += f" ({'; '.join(touched)})"
    return text


def _relative_error(actual, expected) -> float:
    scale = float(np.max(np.abs(expected))) if expected.size else 0.0
    if scale == 0.0:
        return float("inf")
    return float(np.max(np.abs(actual - expected))) / scale


def _index(index) -> str:
    return "[" + ", ".join(str(k) for k in index) + "]" if index else ""


def values(names, rtol, atol, cause="", labels=None, scalar=False, errors=None, atol_scaled=False,
           equivalent=None):
    """A judge comparing the outputs ``names`` of every call with the reference.

    The known mistakes of each call (``ctx.known(k)``, ``{name: [(value, text), ...]}``)
    give the likely cause; ``cause`` is the fallback hint (a string, or ``{name: text}``); ``labels`` maps an
    output to its name in feedback (``{"value": "h"}``); ``errors`` maps an exception
    type name to a likely cause (``{"LinAlgError": "..."}``). ``atol_scaled``: ``atol`` is
    relative to the output's largest reference entry (at least 1), for outputs whose
    entries span orders of magnitude (Jacobians, normal-equation blocks). ``equivalent``: for an
    output whose right answer is not unique (an angle at the end of its range), ``{name: f(got, want,
    call)}`` giving ``got`` with every entry that is as right as the reference's replaced by it.
    """
    labels = labels or {}
    equivalent = equivalent or {}

    def judge(ctx):
        triples, failure = call_fields(ctx, errors)
        for index, (call, got, want) in enumerate(triples):
            known = ctx.known(index)
            for name in names:
                hint = cause.get(name, "") if isinstance(cause, dict) else cause
                tolerance = atol * max(1.0, float(np.max(np.abs(want[name])))) if atol_scaled else atol
                answer = equivalent[name](got[name], want[name], call) if name in equivalent else got[name]
                text = compare(answer, want[name], labels.get(name, name), rtol, tolerance,
                               call.where, known.get(name, ()), hint, scalar, call.groups)
                if text:
                    return Verdict(0.0, text)
        return failure or Verdict(1.0, "ok")

    return judge
