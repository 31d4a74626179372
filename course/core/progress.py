"""A progress line for long runs (compare, demo, benchmark, notebook builds).

One tqdm bar over the runs of a comparison, on stderr: which back end and method is
running and, for ours, the iteration and chi2 as they come (the minimizer's callback).
Quiet when stderr is not a terminal (CI, pipes, notebooks), unless forced.
"""

import sys
from contextlib import contextmanager


class Progress:
    """``with progress.run("ours", "dogleg") as callback: minimize(..., callback=callback)``."""

    def __init__(self, total: int, label: str = "", enabled=None, file=None):
        self.file = file if file is not None else sys.stderr
        self.enabled = bool(enabled if enabled is not None else getattr(self.file, "isatty", lambda: False)())
        self.bar = None
        if self.enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc=label, file=self.file, leave=False, dynamic_ncols=True,
                            bar_format="{desc} {n_fmt}/{total_fmt} runs {elapsed}{postfix}")

    @contextmanager
    def run(self, backend: str, method: str):
        """Around one run; yields the per-iteration callback for our minimizer (or None)."""
        if self.bar is None:
            yield None
            return
        self.bar.set_postfix_str(f"{backend} {method}")

        def callback(record):
            self.bar.set_postfix_str(f"{backend} {method}: iteration {record.iteration}, chi2 {record.chi2:.6g}")

        try:
            yield callback
        finally:
            self.bar.update(1)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def quiet() -> Progress:
    return Progress(0, enabled=False)
