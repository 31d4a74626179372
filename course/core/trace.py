"""Per-iteration records and run results, one schema for our solvers and every peer.

chi2 is always ``sum r^T W r`` (Ceres and GTSAM report half of it: convert).
"""

from dataclasses import asdict, dataclass, field

import numpy as np

from course.core.backend_names import BACKENDS


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
    ``not_run``: empty for a finished solve; otherwise why the pair did not run (e.g.
    ``"not implemented: TODO damping.GavinType1.damping_diagonal"``), and the numbers
    are placeholders (NaN chi2, no params, no trace). See ``RunResult.skipped``.
    ``ate``: the absolute trajectory error against ground truth, where the problem has
    it (``course.problems.posegraph.trajectory.absolute_trajectory_error``), else None.
    ``init``: where the solve started (``course.app.starts.INITIALISERS``: ``file``,
    ``tree``, ``chordal``); ``init_seconds``: the initialisation's own time, not in
    ``seconds`` (0.0 for the file's poses); ``total_seconds`` is the time to solution.
    ``repaired_edges``: how many edges' information the reader repaired (a pose graph read with
    ``information="nearest-psd"`` or ``"isotropic"``, ``course.solver.information``), and
    ``information_repair`` how; ``note`` says it in words.
    ``compile_seconds``: a back end's compilation before its first linearisation (JAX's ``jit``),
    not in ``seconds`` (0.0 where nothing is compiled).
    ``called``: the implementation's functions the run called (``module.qualname``, in the order
    first called; ``course.core.calls``), the code to blame when it ends wrong; ``None`` where nobody
    recorded them.
    ``linear_solve``: the sparse solve of ``H dx = -b`` the run used (ours: ``course.solver.choice``'s
    label, ``ours``, ``cholmod``, ``superlu``, or ``dense``/``schur`` where the problem solves its own
    way; a peer's: its library's solve), ``""`` where unknown.
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
    not_run: str = ""
    ate: dict | None = None
    init: str = "file"
    init_seconds: float = 0.0
    repaired_edges: int = 0
    information_repair: str = ""
    compile_seconds: float = 0.0
    called: tuple | None = None
    linear_solve: str = ""

    def __post_init__(self):
        if self.backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {self.backend!r}")

    @classmethod
    def skipped(cls, backend: str, method: str, reason: str) -> "RunResult":
        """A row for a pair that did not run, saying why."""
        nan = float("nan")
        return cls(backend, method, np.empty(0), nan, nan, 0, 0.0, not_run=reason)

    @property
    def seconds_per_iteration(self) -> float:
        return self.seconds / max(self.iterations, 1)

    @property
    def note(self) -> str:
        """What the run's data had done to it: ``"1 edge's information repaired (nearest-psd)"``,
        or ""."""
        return repair_note(self.repaired_edges, self.information_repair)

    @property
    def total_seconds(self) -> float:
        """Time to solution: the initialisation and the solve."""
        return self.init_seconds + self.seconds

    def to_json(self, with_params: bool = True) -> dict:
        """A JSON-ready dict: the ``runs[]`` entry of ``compare --json``."""
        out = {
            "backend": self.backend,
            "method": self.method,
            "iterations": int(self.iterations),
            "initial_chi2": float(self.initial_chi2),
            "final_chi2": float(self.final_chi2),
            "seconds": float(self.seconds),
            "init": self.init,
            "init_seconds": float(self.init_seconds),
            "stop_reason": self.stop_reason,
            "factorizations": int(self.factorizations),
            "linear_solve": self.linear_solve,
            "trace": [_finite_or_none(asdict(r)) for r in self.trace],
        }
        if self.ate is not None:
            out["ate"] = self.ate
        if self.compile_seconds:
            out["compile_seconds"] = float(self.compile_seconds)
        if self.repaired_edges:
            out.update(repaired_edges=int(self.repaired_edges), information_repair=self.information_repair,
                       note=self.note)
        if self.called is not None:
            out["called"] = list(self.called)
        if self.not_run:  # JSON has no NaN
            out.update(not_run=self.not_run, initial_chi2=None, final_chi2=None)
        if with_params:
            out["params"] = np.asarray(self.params).tolist()
        return out


class RepairedEdges:
    """For a graph's dataclass that has ``repaired`` ((M,) bool, the edges whose information the
    reader repaired) and ``information_repair`` (how): the count and the sentence that says it."""

    repaired: np.ndarray | None
    information_repair: str

    @property
    def num_repaired(self) -> int:
        """How many edges' information the reader repaired."""
        return 0 if self.repaired is None else int(np.count_nonzero(self.repaired))

    @property
    def repair_note(self) -> str:
        """``"3 edges' information repaired (nearest-psd)"``, or "" when none was."""
        return repair_note(self.num_repaired, self.information_repair)


def repair_note(count: int, mode: str) -> str:
    """``"1 edge's information repaired (nearest-psd)"``, ``"3 edges' ..."``; "" for none."""
    if not count:
        return ""
    whose = "1 edge's" if count == 1 else f"{count} edges'"
    return f"{whose} information repaired ({mode})"


def _finite_or_none(record: dict) -> dict:
    """JSON has no NaN: write it as null."""
    return {
        k: (None if isinstance(v, float) and not np.isfinite(v) else v) for k, v in record.items()
    }
