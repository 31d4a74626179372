"""Levenberg-Marquardt as the C++ course code of chapter 1's source runs it: Gavin's type 3
(Nielsen's rule) with the source's constants and its cap, put together from the implementation's
``GavinType3``, no new formula for a student to write.

Against Gavin's type 3 (``lm.m`` defaults), the source changes three things:

- ``lambda_0 = 1e-5 max diag(H)`` (tau = 1e-5, not 1e-2);
- a step is taken when ``rho > 0`` (not ``rho > eps_4 = 0.1``);
- the decrease factor after an accepted step is capped at 2/3:
  ``lambda max(1/3, min(1 - (2 rho - 1)^3, 2/3))``; so lambda falls by at least a third after
  every accepted step, even one whose rho is close to 0 or 1/2.

The source also adds 1e-3 to the gain ratio's denominator (so that it is never zero); ``offset``
does the same (default the source's :data:`SOURCE_OFFSET`; 0 changes no printed chi2 of the run).

On the source's own data (:mod:`course.problems.curve.source_data`), with the cap, every accepted
chi2 the C++ run prints is ours to the printed digit (36048.3, 30015.5, 13421.2, 7273.96, ...,
91.3959); without it the runs part at the fifth (284.4 against 269.3: lambda 1864.17 against 1242.76 after
the third accepted step).
"""

from course.solver.damping import DampingState, DampingStrategy

#: the method name of the source's variant (``--methods lm-source``); not run unless named
SOURCE_NIELSEN = "lm-source"
#: the source's constants
SOURCE_TAU, SOURCE_CAP, SOURCE_OFFSET = 1e-5, 2.0 / 3.0, 1e-3


class SourceNielsen(DampingStrategy):
    """Gavin's type 3 (``nielsen``, built with ``tau``) accepting at ``rho > threshold`` and
    capping the decrease factor at ``cap`` (None: no cap, Gavin's type 3 with other constants)."""

    name = SOURCE_NIELSEN

    def __init__(self, nielsen: DampingStrategy, threshold: float = 0.0, cap: float | None = SOURCE_CAP,
                 offset: float = SOURCE_OFFSET):
        self.nielsen, self.cap, self.offset = nielsen, cap, float(offset)
        self.epsilon_4 = float(threshold)

    def initial_state(self, diag_H):
        return self.nielsen.initial_state(diag_H)

    def damping_diagonal(self, diag_H, lam):
        return self.nielsen.damping_diagonal(diag_H, lam)

    def gain_denominator(self, h, b, diag_H, lam) -> float:
        return float(self.nielsen.gain_denominator(h, b, diag_H, lam)) + self.offset

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        new = self.nielsen.update(state, rho, accepted, alpha=alpha, dchi2=dchi2)
        if accepted and self.cap is not None:
            # max(1/3, min(f, cap)) = min(max(1/3, f), cap) for cap >= 1/3: the rule's lambda, capped
            return DampingState(lam=min(new.lam, self.cap * state.lam), nu=new.nu)
        return new
