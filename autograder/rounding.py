# RELEASE: omit
"""Inputs moved by a few units in the last place: what another CPU, BLAS or LAPACK may as well
have computed. Instructor side: the oracle keeps a known mistake's output only where it survives
such a move (:func:`stable`), and ``tests/test_rounding.py`` renders the public data from moved
inputs to show the data does not turn on rounding.

The move is a function of each number's bits, not of where it sits: the same float moves to the
same float everywhere, so a symmetric matrix stays symmetric, an argument given twice stays equal
and 0 stays 0 (``x (1 + k eps)`` with ``k`` in ``[-ulps, ulps]`` drawn from x's bits).
"""

import dataclasses

import numpy as np

#: how far a move goes, in units of the machine epsilon (relative)
ULPS = 4
#: a known mistake's output is kept when rounding moves it by at most this much of its largest entry.
#: Measured over every check's mistakes, public and hidden (2026-11): kept ones move by at most
#: 1.6e-10 (a Jacobian at a rotation of 1e-9 rad), dropped ones by 1.8e-7 or more (eigenvectors of a
#: repeated eigenvalue, an eigenvalue at its threshold): the line sits in that gap, and a hundred times
#: below the tolerance at which the stale-data test compares mistakes (``MISTAKE_RTOL`` in
#: :mod:`autograder.expected`, as the feedback matches them)
STABLE_RTOL = 3e-9


def _offsets(bits: np.ndarray, ulps: int, salt: int) -> np.ndarray:
    with np.errstate(over="ignore"):
        mixed = (bits ^ np.uint64(salt)) * np.uint64(0x9E3779B97F4A7C15)  # wraps: a hash of the bits
    return ((mixed >> np.uint64(40)) % np.uint64(2 * ulps + 1)).astype(np.int64) - ulps


#: a number whose binary expansion ends within this many significant bits is left where it is
SHORT_BITS = 24


def short(values: np.ndarray) -> np.ndarray:
    """Where ``values`` have at most :data:`SHORT_BITS` significant bits (0, 6.25, 1 + 2^-20, a
    multiple of 1/16): what a check writes to sit exactly on a threshold or at exactly pi, and what
    stays exact through sums and products on every machine, so no BLAS rounds it."""
    mantissa, _ = np.frexp(values)
    scaled = np.ldexp(mantissa, SHORT_BITS)
    return np.isfinite(values) & (scaled == np.round(scaled))


def moved(value, ulps: int = ULPS, salt: int = 0):
    """``value`` with every float (numpy float64 arrays, Python floats, inside tuples, lists and
    dicts) moved by at most ``ulps`` relative epsilons; everything else as it is."""
    if isinstance(value, np.ndarray) and value.dtype == np.float64:
        k = np.where(short(value), 0, _offsets(value.view(np.uint64), ulps, salt))
        return np.asarray(value * (1.0 + k * np.finfo(float).eps)).reshape(value.shape)
    if isinstance(value, float):  # np.float64 too
        return type(value)(moved(np.array([value], dtype=np.float64), ulps, salt)[0])
    if isinstance(value, tuple):
        return tuple(moved(v, ulps, salt) for v in value)
    if isinstance(value, list):
        return [moved(v, ulps, salt) for v in value]
    if isinstance(value, dict):
        return {k: moved(v, ulps, salt) for k, v in value.items()}
    return value


def moved_call(call, ulps: int = ULPS, salt: int = 0):
    """``call`` with its arguments and keyword arguments :func:`moved`."""
    return dataclasses.replace(call, args=moved(call.args, ulps, salt), kwargs=moved(call.kwargs, ulps, salt))


def close(a, b) -> bool:
    """Whether two outputs agree: the same shape, finite, every entry within ``STABLE_RTOL`` of the
    largest."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return False
    if not b.size:
        return True
    # a finite scale means a finite b; under a finite bound, a's inf or nan fails the comparison
    scale = float(np.max(np.abs(b)))
    return scale < np.inf and bool(np.all(np.abs(a - b) <= STABLE_RTOL * scale))


def stable(known: dict, again: dict) -> dict:
    """The known mistakes ``{key: [(value, why), ...]}`` of a call that ``again`` (the same
    mistakes on the moved call) gives too, with a :func:`close` value; a mistake that is not finite,
    or that rounding moves (it reads a rank decision at its threshold, an eigenvector of a repeated
    eigenvalue, a difference that cancels), is dropped: it would differ between machines."""
    return {key: [(value, why) for value, why in pairs
                  if any(other_why == why and close(value, other) for other, other_why in again.get(key, ()))]
            for key, pairs in known.items()}
