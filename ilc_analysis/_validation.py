"""Input validation shared by every module: one shape validator, one finiteness check."""

from __future__ import annotations

import numbers
from collections.abc import Sequence

import numpy as np

from .exceptions import ParameterError, ShapeError

__all__ = ["as_matrix", "as_vector", "as_finite_array", "positive", "nonnegative", "in_interval",
           "positive_int"]


def _describe(shape: Sequence[int | None]) -> str:
    parts = ["any" if s is None else str(s) for s in shape]
    return "(" + ", ".join(parts) + ("," if len(parts) == 1 else "") + ")"


def as_finite_array(value, name: str, *, ndim: int | None = None,
                    shape: Sequence[int | None] | None = None) -> np.ndarray:
    """Return ``value`` as a finite float array, checking its rank and shape.

    Parameters
    ----------
    value : array_like
        The user's input. It is never reshaped or broadcast silently.
    name : str
        The parameter name used in error messages.
    ndim : int, optional
        Required number of dimensions.
    shape : sequence of int or None, optional
        Required shape; ``None`` entries match any size.

    Raises
    ------
    ShapeError
        If the rank or shape differs; the message gives expected and found shapes.
    ParameterError
        If the array is not numeric or contains NaN/inf.
    """
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ParameterError(f"{name} must be numeric; got {type(value).__name__}") from exc
    if shape is not None:
        ndim = len(shape)
    if ndim is not None and arr.ndim != ndim:
        expected = _describe(shape) if shape is not None else f"{ndim}-D"
        raise ShapeError(f"{name} must have shape {expected}; found shape {arr.shape}")
    if shape is not None:
        for want, got in zip(shape, arr.shape, strict=True):
            if want is not None and want != got:
                raise ShapeError(
                    f"{name} must have shape {_describe(shape)}; found shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must be finite; it contains NaN or inf")
    return arr


def as_matrix(value, name: str, rows: int | None = None, cols: int | None = None) -> np.ndarray:
    """A finite 2-D float array of shape ``(rows, cols)`` (``None`` = any)."""
    return as_finite_array(value, name, shape=(rows, cols))


def as_vector(value, name: str, size: int | None = None) -> np.ndarray:
    """A finite 1-D float array of length ``size`` (``None`` = any)."""
    return as_finite_array(value, name, shape=(size,))


def _scalar(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number; got {value!r}")
    v = float(value)
    if not np.isfinite(v):
        raise ParameterError(f"{name} must be finite; got {value!r}")
    return v


def positive(value, name: str) -> float:
    """A finite real number > 0."""
    v = _scalar(value, name)
    if v <= 0:
        raise ParameterError(f"{name} must be positive; got {value!r}")
    return v


def nonnegative(value, name: str) -> float:
    """A finite real number >= 0."""
    v = _scalar(value, name)
    if v < 0:
        raise ParameterError(f"{name} must be non-negative; got {value!r}")
    return v


def in_interval(value, name: str, low: float, high: float, *, closed_high: bool = False) -> float:
    """A finite real number in ``[low, high)`` (or ``[low, high]`` with ``closed_high``)."""
    v = _scalar(value, name)
    ok = low <= v <= high if closed_high else low <= v < high
    if not ok:
        bracket = "]" if closed_high else ")"
        raise ParameterError(f"{name} must lie in [{low}, {high}{bracket}; got {value!r}")
    return v


def positive_int(value, name: str, minimum: int = 1) -> int:
    """An integer >= ``minimum`` (bools and floats are rejected, not truncated)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ParameterError(f"{name} must be an integer >= {minimum}; got {value!r}")
    if int(value) < minimum:
        raise ParameterError(f"{name} must be an integer >= {minimum}; got {value!r}")
    return int(value)


# Size caps of user-chosen problem sizes (the command line refuses larger values with exit 2
# before any work; without them -N 100000 asks for 149 GiB and substeps = 1e8 never ends).
#: Largest number of entries of a dense lifted matrix, (N n_y) x (N n_u): 2**27 float64 entries
#: are 1 GiB (N = 8192 for one input and two outputs).
MAX_LIFTED_ENTRIES = 2**27
#: Largest number of RK4 sub-steps per sample of a simulated scenario.
MAX_SUBSTEPS = 1_000
#: Largest number of learning iterations of a simulated scenario.
MAX_ITERATIONS = 10_000
