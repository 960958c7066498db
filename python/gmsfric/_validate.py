"""Argument checks shared by the Python layer (the core re-checks everything it receives)."""

from __future__ import annotations

import sys
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidInputError


def float_array(name: str, values: ArrayLike) -> NDArray[np.float64]:
    """A contiguous float64 view of ``values`` (no copy when it already is one), at least 1-D;
    ``InvalidInputError`` naming ``name`` for a missing or non-numeric input."""
    if values is None:
        raise InvalidInputError(f"`{name}` is missing (None)")
    try:
        arr = np.ascontiguousarray(values, dtype=np.float64)
    except (TypeError, ValueError, OverflowError) as exc:
        raise InvalidInputError(f"`{name}` must be numeric: {exc}") from None
    return arr.reshape(1) if arr.ndim == 0 else arr


def as_array(name: str, values: ArrayLike, *, min_len: int = 1) -> NDArray[np.float64]:
    """A 1-D contiguous float64 view of ``values`` (no copy when it already is one).

    Raises ``InvalidInputError`` naming ``name`` for non-numeric, non-1-D, empty, too short or
    non-finite input.
    """
    arr = float_array(name, values)
    if arr.ndim != 1:
        raise InvalidInputError(f"`{name}` must be one-dimensional, got shape {arr.shape}")
    if arr.size < min_len:
        raise InvalidInputError(f"`{name}` is empty or too short: {arr.size} sample(s), need at least {min_len}")
    if not np.isfinite(arr).all():
        first = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidInputError(f"`{name}` has a non-finite value ({arr[first]}) at index {first}")
    return arr


#: Largest magnitude of a measured signal, or of a position over the squared time step (the scale of
#: its acceleration): fits square and sum these over up to 1e12 rows, through filters that may
#: amplify them, and beyond this the sums overflow and every fitted number comes out nan.
MAX_SIGNAL_MAGNITUDE = float(np.sqrt(np.finfo(np.float64).max)) * 1e-7

#: Smallest peak of a measured signal that is not zero throughout: below it, squares and noise
#: estimates underflow to zero and the fits divide by them.
MIN_SIGNAL_MAGNITUDE = 1.0 / MAX_SIGNAL_MAGNITUDE


def within_fit_range(label: str, values: NDArray[np.float64], *, time_step: float | None = None,
                     error: type[InvalidInputError] = InvalidInputError) -> None:
    """Raise ``error`` naming ``label`` when ``values`` peak below :data:`MIN_SIGNAL_MAGNITUDE`
    (without being zero throughout) or exceed :data:`MAX_SIGNAL_MAGNITUDE`, or,
    given the smallest ``time_step`` of a position, when the position over that step squared (the
    scale of its acceleration) does: no unit of a real axis gets there, so it is a wrong unit or a
    corrupt log, and the fits would only return nan."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        # the callers have refused NaN already; max and min borrow the array, abs would copy it
        peak = np.float64(max(float(values.max()), -float(values.min()), 0.0)) if values.size else np.float64(0.0)
        scaled = peak / np.square(np.float64(time_step)) if time_step is not None and peak else peak
    if 0 < peak < MIN_SIGNAL_MAGNITUDE:
        raise error(f"{label} reaches only {peak:.3g}, below {MIN_SIGNAL_MAGNITUDE:.1e} where the fits underflow; check its unit")
    if not scaled <= MAX_SIGNAL_MAGNITUDE:
        if time_step is None:
            raise error(f"{label} reaches {peak:.3g}, beyond {MAX_SIGNAL_MAGNITUDE:.1e} where the fits overflow; check its unit")
        raise error(f"{label} reaches {peak:.3g} with time steps down to {time_step:.3g}, an acceleration of {scaled:.3g}, "
                    f"beyond {MAX_SIGNAL_MAGNITUDE:.1e} where the fits overflow; check the units of position and time")


def measured_signal(name: str, values: ArrayLike, *, min_len: int = 1) -> NDArray[np.float64]:
    """:func:`as_array` for a measured signal that a fit squares and sums: also refused outside
    :data:`MIN_SIGNAL_MAGNITUDE` to :data:`MAX_SIGNAL_MAGNITUDE` (see :func:`within_fit_range`)."""
    arr = as_array(name, values, min_len=min_len)
    within_fit_range(f"`{name}`", arr)
    return arr


def same_length(name: str, arr: NDArray[Any], other: str, n: int) -> None:
    if arr.size != n:
        raise InvalidInputError(f"`{name}` has length {arr.size} but `{other}` has length {n}: they must match")


def show(value: Any) -> str:
    """A short form of a bad value for a message (a 400-digit integer or a long array is not
    printed whole)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**20:
        return f"an integer of {len(str(abs(value)))} digits"
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape} ({value.dtype})"
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def choice(name: str, value: Any, options: Sequence[str]) -> str:
    """``value`` if it is one of the strings ``options``; anything else (another string, a
    number, an array) raises ``InvalidInputError`` naming ``name`` and the options."""
    if not isinstance(value, str) or value not in options:
        listed = ", ".join(repr(o) for o in options)
        raise InvalidInputError(f"`{name}` must be one of {listed}, got {show(value)}")
    return value


def number(name: str, value: Any) -> float:
    """``value`` as a float (NaN and inf pass: the core names them); anything that is not a real
    number (a bool, a string, even a numeric one), or does not fit a double, raises
    ``InvalidInputError`` naming ``name``."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or isinstance(value, (complex, np.complexfloating)):
        raise InvalidInputError(f"`{name}` must be a real number, got {show(value)}")
    try:
        return float(value)
    except OverflowError:
        raise InvalidInputError(f"`{name}` = {show(value)} does not fit a double") from None
    except (TypeError, ValueError):
        raise InvalidInputError(f"`{name}` must be a number, got {show(value)}") from None


def finite(name: str, value: float) -> float:
    v = number(name, value)
    if not np.isfinite(v):
        raise InvalidInputError(f"`{name}` must be finite, got {v}")
    return v


def count(name: str, value: Any, *, minimum: int = 1, maximum: int | None = None) -> int:
    """A whole number in ``[minimum, maximum]`` (bools and non-integral floats refused); without
    ``maximum``, at most ``sys.maxsize`` (what the core can hold)."""
    if isinstance(value, (bool, np.bool_)):
        raise InvalidInputError(f"`{name}` must be an integer, got {show(value)}")
    try:
        as_int = int(value)
        whole = as_int == value
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"`{name}` must be an integer, got {show(value)}") from None
    if not whole:
        raise InvalidInputError(f"`{name}` must be an integer, got {show(value)}")
    if as_int < minimum or (maximum is not None and as_int > maximum):
        bound = f"between {minimum} and {maximum}" if maximum is not None else f">= {minimum}"
        raise InvalidInputError(f"`{name}` must be {bound}, got {show(as_int)}")
    if maximum is None and as_int > sys.maxsize:
        raise InvalidInputError(f"`{name}` = {show(as_int)} is too large (at most {sys.maxsize})")
    return as_int


def positive(name: str, value: float) -> float:
    v = finite(name, value)
    if v <= 0:
        raise InvalidInputError(f"`{name}` must be > 0, got {v}")
    return v


def step(name: str, value: float) -> float:
    """A time step (s): positive, finite, not subnormal, with a finite reciprocal (the core's rule)."""
    v = positive(name, value)
    if v < np.finfo(np.float64).tiny or not np.isfinite(1.0 / v):
        raise InvalidInputError(f"`{name}` = {v:g} s is too small a step (its reciprocal overflows)")
    return v


def non_negative(name: str, value: float) -> float:
    v = finite(name, value)
    if v < 0:
        raise InvalidInputError(f"`{name}` must be >= 0, got {v}")
    return v


#: Default ceiling of one call's memory (bytes): the environment variable GMSFRIC_MAX_BYTES overrides it.
DEFAULT_MAX_BYTES = 4 * 1024**3


def max_bytes() -> float:
    """The largest memory (bytes) one call may ask for: ``GMSFRIC_MAX_BYTES`` or 4 GiB."""
    import os

    text = os.environ.get("GMSFRIC_MAX_BYTES")
    if text is None:
        return float(DEFAULT_MAX_BYTES)
    try:
        value = float(text)
    except ValueError:
        raise InvalidInputError(f"GMSFRIC_MAX_BYTES must be a number of bytes, got {text!r}") from None
    if not value > 0:
        raise InvalidInputError(f"GMSFRIC_MAX_BYTES must be > 0, got {text!r}")
    return value


def format_bytes(n: float) -> str:
    """``"728 TiB"``."""
    if not np.isfinite(n):
        return "an unbounded amount"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if abs(n) < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} EiB"  # pragma: no cover


def allocation(what: str, nbytes: float) -> None:
    """Refuse, before allocating, a request for more memory than :func:`max_bytes`
    (``InvalidInputError`` naming ``what`` and the size asked for)."""
    limit = max_bytes()
    if not np.isfinite(nbytes) or nbytes > limit:
        raise InvalidInputError(f"{what} would need {format_bytes(nbytes)} of memory, more than the {format_bytes(limit)} allowed "
                                "(set GMSFRIC_MAX_BYTES to raise the limit)")
