"""The source's own data: the C++ course code's curve fit, its noise drawn in numpy as the C++
standard library that ran it (GCC's libstdc++) draws it.

The C++ code draws ``y_i = exp(a x_i^2 + b x_i + c) + n_i`` with ``a, b, c = 1, 2, 1``,
``x_i = i / 100`` for i = 0..99 and ``n_i`` from ``std::normal_distribution<double>(0, 1)`` on a
default-constructed ``std::default_random_engine``. In libstdc++:

- ``default_random_engine`` is ``minstd_rand0``: ``x_{k+1} = 16807 x_k mod (2^31 - 1)``, seed 1,
  values in [1, 2^31 - 2];
- a uniform double is ``generate_canonical<double, 53>``: ``r = max - min + 1 = 2^31 - 2`` holds
  ``floor(log2 r) = 30`` bits, so it takes ``ceil(53 / 30) = 2`` draws,
  ``u = ((x1 - 1) + (x2 - 1) r) / r^2``, in double arithmetic (``r^2`` rounded to double);
- ``normal_distribution`` is Marsaglia's polar method: ``x = 2 u - 1``, ``y = 2 u' - 1`` until
  ``0 < s = x^2 + y^2 <= 1``, then ``m = sqrt(-2 log(s) / s)``; it returns ``y m`` and keeps ``x m``
  for the next call.

The data give chi2 36048.3 at (0, 0, 0), the first line the C++ run prints
(``tests/test_source_data.py``).
"""

import math

import numpy as np

from course.problems.curve.problem import START, TRUTH, CurveData

#: minstd_rand0's multiplier and modulus
MINSTD_A, MINSTD_M = 16807, 2**31 - 1
#: the range of its values, max - min + 1
MINSTD_RANGE = MINSTD_M - 2 + 1


class MinstdRand0:
    """``std::minstd_rand0`` (``std::default_random_engine`` in libstdc++), seed 1 by default."""

    def __init__(self, seed: int = 1):
        seed %= MINSTD_M
        self.state = seed if seed != 0 else 1

    def __call__(self) -> int:
        self.state = (MINSTD_A * self.state) % MINSTD_M
        return self.state


def canonical(engine: MinstdRand0) -> float:
    """``std::generate_canonical<double, 53>(engine)`` as libstdc++ computes it (two draws)."""
    total = float(engine() - 1)
    scale = float(MINSTD_RANGE)
    total += float(engine() - 1) * scale
    scale = float(scale * MINSTD_RANGE)  # exact in long double, then rounded to double, as in C++
    value = total / scale
    return value if value < 1.0 else math.nextafter(1.0, 0.0)


class PolarNormal:
    """``std::normal_distribution<double>(mean, stddev)`` of libstdc++ (Marsaglia's polar method)."""

    def __init__(self, mean: float = 0.0, stddev: float = 1.0):
        self.mean, self.stddev = mean, stddev
        self.saved: float | None = None

    def __call__(self, engine: MinstdRand0) -> float:
        if self.saved is not None:
            value, self.saved = self.saved, None
        else:
            while True:
                x = 2.0 * canonical(engine) - 1.0
                y = 2.0 * canonical(engine) - 1.0
                s = x * x + y * y
                if 0.0 < s <= 1.0:
                    break
            mult = math.sqrt(-2.0 * math.log(s) / s)
            self.saved = x * mult
            value = y * mult
        return value * self.stddev + self.mean


def source_data(num_points: int = 100, sigma: float = 1.0, truth=TRUTH, start=START, seed: int = 1) -> CurveData:
    """The C++ course code's curve-fitting data (``x_i = i / 100``, unit weights), seed 1 as it runs."""
    engine, noise = MinstdRand0(seed), PolarNormal(0.0, sigma)
    x = np.arange(num_points) / 100.0
    a, b, c = truth
    y = np.array([math.exp(a * xi * xi + b * xi + c) + noise(engine) for xi in x])
    return CurveData(x, y, np.ones(num_points), np.array(truth, float), np.array(start, float), sigma, seed)
