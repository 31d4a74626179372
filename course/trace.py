"""Per-iteration records and run results, one schema for our solvers and every peer.

chi2 is always ``sum r^T W r`` (Ceres and GTSAM report half of it: convert).
"""

from dataclasses import asdict, dataclass, field

import numpy as np

BACKENDS = ("ours", "ceres", "g2o", "gtsam", "scipy")


@dataclass
class IterationRecord:
    """One step attempt. Iteration 0 is the starting point (no step).

    ``damping`` is lambda (LM) or the trust-region radius (dogleg); NaN where
    the method has none. ``seconds`` is the time since the solve started.
    """

    iteration: int
    chi2: float
    damping: float = float("nan")
    rho: float = float("nan")
    step_norm: float = float("nan")
    accepted: bool = True
    seconds: float = 0.0
    factorizations: int = 0


@dataclass
class RunResult:
    """A finished solve.

    ``params``: the final estimate (flat ``(n,)`` or ``(N, 3)`` poses).
    ``seconds``: the solve alone, no loading or set-up.
    ``iterations``: step attempts, accepted or not.
    ``final_chi2``: evaluated with the framework's own error on ``params``.
    """

    backend: str
    method: str
    params: np.ndarray
    initial_chi2: float
    final_chi2: float
    iterations: int
    seconds: float
    trace: list = field(default_factory=list)
    stop_reason: str = ""
    factorizations: int = 0

    def __post_init__(self):
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {self.backend!r}")

    @property
    def seconds_per_iteration(self) -> float:
        return self.seconds / max(self.iterations, 1)

    def to_json(self, with_params: bool = True) -> dict:
        """A JSON-ready dict: the ``runs[]`` entry of ``compare --json``."""
        out = {
            "backend": self.backend,
            "method": self.method,
            "iterations": int(self.iterations),
            "initial_chi2": float(self.initial_chi2),
            "final_chi2": float(self.final_chi2),
            "seconds": float(self.seconds),
            "stop_reason": self.stop_reason,
            "factorizations": int(self.factorizations),
            "trace": [_finite_or_none(asdict(r)) for r in self.trace],
        }
        if with_params:
            out["params"] = np.asarray(self.params).tolist()
        return out


def _finite_or_none(record: dict) -> dict:
    """JSON has no NaN: write it as null."""
    return {
        k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in record.items()
    }
