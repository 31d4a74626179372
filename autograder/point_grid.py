"""Points on one grid: every score, maximum and total is a whole number of steps of 0.0001 points.

Why. With ``total = 100`` spread over 78 points' worth of checks, a check is worth 1.2820512...
points. A score rounded to 4 decimals (1.2821) beside a maximum that is not (1.282051) is not full
marks, and a float sum of 44 such maxima is not 100. So:

- a check's maximum is put on the grid where the course configuration computes it, by largest
  remainders (:func:`apportion`): the maxima of a group sum exactly to the group's exact sum
  rounded to the grid (to the ``total`` when one is given), each within one step of its share;
- a score is ``maximum * fraction`` put on the grid (:func:`scaled`): the fraction 1 gives the
  maximum itself, by construction, and a late penalty's fraction scales a total the same way;
- a sum is taken in whole steps (:func:`total`), never as floats, so that the sum of full scores
  is the sum of the maxima, exactly.

A value on the grid is the float nearest ``n / 10000``: written to JSON or a CSV and read back,
it gives the same ``n``, so a record's totals are recomputed exactly wherever they are read (the
gradebook, the report, the LMS files). Numbers are read as written (``0.3`` is 3/10, not the
binary float's expansion); halves of a step round to even.
"""

from fractions import Fraction
from numbers import Rational

#: decimals of a point kept (Gradescope shows two; the CSVs four)
DECIMALS = 4
#: steps per point
STEPS = 10**DECIMALS


def exact(value) -> Fraction:
    """``value`` (an int, a float as written, a Fraction, a numeric string) as a Fraction;
    ``ValueError`` for a value that is not a finite number."""
    if isinstance(value, bool):
        raise ValueError(f"not a number of points: {value!r}")
    if isinstance(value, Rational):
        return Fraction(value)
    try:
        return Fraction(repr(float(value)) if isinstance(value, float) else str(value).strip())
    except (ValueError, ZeroDivisionError, OverflowError):
        raise ValueError(f"not a finite number of points: {value!r}") from None


def steps(value) -> int:
    """``value`` in whole steps of the grid (rounded half to even)."""
    return round(exact(value) * STEPS)


def of_steps(count: int) -> float:
    """The float of ``count`` steps (the nearest to ``count / 10000``)."""
    return count / STEPS


def on_grid(value) -> float:
    """``value`` rounded to the grid."""
    return of_steps(steps(value))


def is_on_grid(value) -> bool:
    """True when ``value`` is a whole number of steps as written."""
    return (exact(value) * STEPS).denominator == 1


def scaled(maximum, fraction) -> float:
    """``maximum * fraction`` on the grid, ``fraction`` clipped to [0, 1]: 1 gives ``on_grid(maximum)``."""
    kept = min(max(exact(fraction), Fraction(0)), Fraction(1))
    return of_steps(round(steps(maximum) * kept))


def total(values) -> float:
    """The sum of ``values``, each on the grid, in whole steps: exact."""
    return of_steps(sum(steps(value) for value in values))


def apportion(shares: dict) -> dict:
    """``{name: points on the grid}`` for exact ``shares`` ``{name: points}``: each share rounded down
    to the grid, then one step more to the largest remainders (the first named among equal ones) until
    the sum is the shares' exact sum rounded to the grid (Hamilton's method). A share already on the
    grid is kept as it is."""
    exact_steps = {name: exact(share) * STEPS for name, share in shares.items()}
    floors = {name: value.numerator // value.denominator for name, value in exact_steps.items()}
    left = round(sum(exact_steps.values(), Fraction(0))) - sum(floors.values())
    order = sorted(exact_steps, key=lambda name: -(exact_steps[name] - floors[name]))  # stable: ties by order
    for name in order[:left]:
        floors[name] += 1
    return {name: of_steps(floors[name]) for name in shares}
