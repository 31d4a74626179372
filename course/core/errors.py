"""Errors the framework raises with a message a student can act on."""


class CourseError(Exception):
    """Base class of the framework's own errors."""


class SingularSystemError(CourseError, ArithmeticError):
    """A linear system could not be factorized (not positive definite)."""


class NonFiniteError(CourseError, ArithmeticError):
    """An implementation returned NaN or inf."""


class ShapeError(CourseError, ValueError):
    """An implementation returned an array of the wrong shape."""


class ContractError(CourseError, ValueError):
    """An implementation returned an array of the right shape that breaks its contract (e.g. a
    fixed pose's rows of H not held)."""


def check_array(value, shape, where: str, what: str):
    """Return ``value`` as a float array of ``shape`` (None = any length), or raise.

    ``where`` names the function that produced it, ``what`` the output.
    """
    import numpy as np

    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ShapeError(f"{where} returned {what} of type {type(value).__name__}: {exc}") from None
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
        expected = "(" + ", ".join("?" if s is None else str(s) for s in shape) + ")"
        raise ShapeError(f"{where} returned {what} of shape {arr.shape}, expected {expected}")
    if not np.all(np.isfinite(arr)):
        index = tuple(int(k) for k in np.argwhere(~np.isfinite(arr))[0])
        raise NonFiniteError(
            f"{where} returned a non-finite {what}: {what}{list(index)} = {arr[index]}"
        )
    return arr


class DatasetError(CourseError, ValueError):
    """A dataset that cannot be found or read; the message names the file and line."""


class MissingDataError(DatasetError):
    """A named dataset whose file is not on this machine. ``short`` says what is missing (for a
    listing's row); the message adds how to get it and what works without it
    (``course.core.data.missing_data_help``)."""

    def __init__(self, short: str, help_text: str = ""):
        super().__init__(f"{short}. {help_text}" if help_text else short)
        self.short = short
