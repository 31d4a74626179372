# RELEASE: omit
"""Known mistakes in ``jets`` (see ``autograder.mistakes``): each derivative rule with one slip,
computed from the call's operands in plain numpy."""

import numpy as np


def _parts(spec):
    if spec[0] == "jet":
        return np.asarray(spec[1], dtype=float), np.asarray(spec[2], dtype=float)
    return np.asarray(spec[1], dtype=float), None


def _k(call):
    return next(np.shape(s[2])[-1] for s in call.args[1] if s[0] == "jet")


def _t(factor, grad):
    return np.asarray(factor)[..., None] * grad


def _g(grad, shape, k):
    return np.zeros(tuple(shape) + (k,)) if grad is None else np.broadcast_to(grad, tuple(shape) + (k,))


def _out(value, grad):
    return {"value": np.asarray(value, dtype=float), "grad": np.asarray(grad, dtype=float)}


def _binary(call, rule):
    (a, da), (b, db) = (_parts(s) for s in call.args[1])
    value = rule[0](a, b)
    k = _k(call)
    return _out(value, rule[1](a, _g(da, np.shape(a), k), b, _g(db, np.shape(b), k)))


def _slips(call):
    op = call.args[0]
    k = _k(call)
    ops = call.args[1]
    errors = np.errstate(all="ignore")
    errors.__enter__()
    try:
        if op == "mul":
            return [(_binary(call, (np.multiply, lambda a, da, b, db: _t(b, da))),
                     "the product rule has two terms: d(ab) = b da + a db"),
                    (_binary(call, (np.multiply, lambda a, da, b, db: _t(a, da) + _t(b, db))),
                     "each operand's derivative is multiplied by the other operand: b da + a db, not a da + b db"),
                    (_binary(call, (np.multiply, lambda a, da, b, db: da * db if db is not None else _t(b, da))),
                     "derivatives do not multiply: eps^2 = 0 in a dual number, so d(ab) = b da + a db")]
        if op == "truediv":
            return [(_binary(call, (np.divide, lambda a, da, b, db: _t(1 / b, da) + _t(a / b**2, db))),
                     "the quotient rule subtracts: d(a/b) = da / b - a db / b^2"),
                    (_binary(call, (np.divide, lambda a, da, b, db: _t(1 / b, da) - _t(a / b, db))),
                     "d(1/b) = -db / b^2: the second term is divided by b twice"),
                    (_binary(call, (np.divide, lambda a, da, b, db: _t(1 / b, da))),
                     "a quotient depends on its denominator too: -a db / b^2"),
                    (_binary(call, (np.divide, lambda a, da, b, db: _t(1 / b, _t(b, da) - _t(a, db)))),
                     "(b da - a db) / b^2: divided by b once only")]
        if op == "pow":
            (x, dx), p = _parts(ops[0]), float(ops[1][1])
            return [(_out(x**p, _t(p * x**p, dx)), "d(x^p) = p x^(p-1) dx: the power decreases by one"),
                    (_out(x**p, _t(x ** (p - 1.0), dx)), "d(x^p) = p x^(p-1) dx: the factor p is missing"),
                    # the unguarded power: its nan is named by the check's nan cause (a known mistake's
                    # output is kept where finite, autograder.oracle.compute), its other entries here
                    (_out(x**p, _t(p * x ** (p - 1.0), dx)) if 0.0 < p < 1.0 else None,
                     "for 0 < p < 1 at x = 0, p x^(p-1) dx is 0 * inf = nan where dx = 0: nothing depends on the "
                     "seeds there, so the derivative is 0 (as sqrt's); keep +-inf where dx is not 0"),
                    ]
        if op == "sqrt":
            x, dx = _parts(ops[0])
            root = np.sqrt(x)
            return [(_out(root, _t(1.0 / root, dx)), "d sqrt(x) = dx / (2 sqrt(x)): the 1/2 is missing"),
                    (_out(root, _t(0.5 * root, dx)), "d sqrt(x) = dx / (2 sqrt(x)), not sqrt(x) dx / 2"),
                    (_out(root, np.where(np.asarray(x)[..., None] == 0.0, 0.0, _t(0.5 / np.where(x == 0, 1, root), dx))),
                     "at x = 0 the derivative is infinite where x's derivative is not 0 (+-inf in its sign): "
                     "sqrt is not differentiable at 0, and the Jet says so")]
        if op in ("sin", "cos", "exp", "log"):
            x, dx = _parts(ops[0])
            value = {"sin": np.sin, "cos": np.cos, "exp": np.exp, "log": np.log}[op](x)
            wrong = {"sin": [(-np.cos(x), "d sin(x) = +cos(x) dx"), (np.sin(x), "d sin(x) = cos(x) dx, not sin(x) dx")],
                     "cos": [(np.sin(x), "d cos(x) = -sin(x) dx: the sign"), (-np.cos(x), "d cos(x) = -sin(x) dx")],
                     "exp": [(x * np.exp(x), "d exp(x) = exp(x) dx"), (np.ones_like(x), "d exp(x) = exp(x) dx")],
                     "log": [(np.ones_like(x), "d log(x) = dx / x: the 1/x is missing"),
                             (-1.0 / x, "d log(x) = +dx / x")]}[op]
            return [(_out(value, _t(f, dx)), why) for f, why in wrong]
        if op == "arctan2":
            (y, dy), (x, dx) = (_parts(s) for s in ops)
            scale = np.maximum(np.abs(x), np.abs(y))
            xs, ys = x / scale, y / scale
            r = scale * (xs * xs + ys * ys)  # x^2 + y^2 = scale * r
            r2 = x * x + y * y
            dy, dx = _g(dy, np.shape(y), k), _g(dx, np.shape(x), k)
            value = np.arctan2(y, x)
            return [(_out(value, _t(ys / r, dy) - _t(xs / r, dx)), "d atan2(y, x) = (x dy - y dx) / (x^2 + y^2): "
                     "x goes with dy and y with dx"),
                    (_out(value, _t(xs / r, dy) + _t(ys / r, dx)), "d atan2(y, x) = (x dy - y dx) / (x^2 + y^2): "
                     "the dx term is subtracted"),
                    (_out(np.arctan(y / x), _t(xs / r, dy) - _t(ys / r, dx)),
                     "arctan(y / x) loses the quadrant (and divides by 0 on the y axis): the value is numpy's "
                     "arctan2(y, x)"),
                    (_out(value, _t(x / r2, dy) - _t(y / r2, dx)),
                     "x^2 + y^2 overflows to inf beyond about 1e154 and underflows to 0 below about 1e-154: divide "
                     "x and y by max(|x|, |y|) before squaring (x / (x^2 + y^2) = (x/s) / (s ((x/s)^2 + (y/s)^2)))")]
        if op == "matmul":
            (A, dA), (B, dB) = (_parts(s) for s in ops)
            column = np.ndim(B) == 1
            Bm = B[..., None] if column else B
            dA = _g(dA, np.shape(A), k)
            dB = _g(dB, np.shape(B), k)
            dBm = dB[..., None, :] if column else dB
            value = A @ Bm
            right = np.einsum("...ijk,...jl->...ilk", dA, Bm) + np.einsum("...ij,...jlk->...ilk", A, dBm)
            swapped = np.einsum("...ijk,...jl->...ilk", dA, Bm) + np.einsum("...ji,...jlk->...ilk", A, dBm) \
                if np.shape(A)[-1] == np.shape(A)[-2] else None
            half = np.einsum("...ijk,...jl->...ilk", dA, Bm) if ops[0][0] == "jet" and ops[1][0] == "jet" else None
            out = []
            if swapped is not None:
                out.append((_out(value[..., 0] if column else value, swapped[..., 0, :] if column else swapped),
                            "d(A B) = dA B + A dB: A is not transposed"))
            if half is not None:
                out.append((_out(value, half), "d(A B) = dA B + A dB: both factors vary"))
            out.append((_out((value[..., 0] if column else value) * 1.0,
                              (right[..., 0, :] if column else right) * 0.5), "no factor 1/2 in the product rule"))
            return out
        return []
    finally:
        errors.__exit__(None, None, None)


def _known(call, ref):
    known = {"value": [], "grad": []}
    for slip, why in _slips(call):
        if slip is None:
            continue
        for name in ("value", "grad"):
            value = np.asarray(slip[name], dtype=float)
            want = np.asarray(ref[name], dtype=float)
            # a slip that coincides with the reference here (the transpose of a symmetric A) is left out, to
            # rounding: the reference may take another path than the slip's einsum, on another CPU another one
            if value.shape == want.shape and not np.allclose(np.nan_to_num(value), np.nan_to_num(want),
                                                            rtol=1e-12, atol=1e-14):
                known[name].append((value, why))
    return known


MISTAKES = {f"jets.Jet: {title}": _known for title in ("product and quotient", "powers")}
MISTAKES.update({"jets.sqrt: sqrt, also at 0": _known, "jets.sin: sin": _known, "jets.cos: cos": _known,
                 "jets.exp: exp": _known, "jets.log: log": _known, "jets.arctan2: arctan2": _known,
                 "jets.matmul: matrix products": _known})
