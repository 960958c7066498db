"""Argument checks shared by the Python layer (the core re-checks everything it receives)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidInputError


def as_array(name: str, values: ArrayLike, *, min_len: int = 1) -> NDArray[np.float64]:
    """A 1-D contiguous float64 view of ``values`` (no copy when it already is one).

    Raises ``InvalidInputError`` naming ``name`` for non-numeric, non-1-D, empty, too short or
    non-finite input.
    """
    try:
        arr = np.ascontiguousarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"`{name}` must be numeric: {exc}") from None
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1:
        raise InvalidInputError(f"`{name}` must be one-dimensional, got shape {arr.shape}")
    if arr.size < min_len:
        raise InvalidInputError(f"`{name}` is empty or too short: {arr.size} sample(s), need at least {min_len}")
    if not np.isfinite(arr).all():
        first = int(np.flatnonzero(~np.isfinite(arr))[0])
        raise InvalidInputError(f"`{name}` has a non-finite value ({arr[first]}) at index {first}")
    return arr


def same_length(name: str, arr: NDArray[Any], other: str, n: int) -> None:
    if arr.size != n:
        raise InvalidInputError(f"`{name}` has length {arr.size} but `{other}` has length {n}: they must match")


def finite(name: str, value: float) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InvalidInputError(f"`{name}` must be a number, got {value!r}") from None
    if not np.isfinite(v):
        raise InvalidInputError(f"`{name}` must be finite, got {v}")
    return v


def positive(name: str, value: float) -> float:
    v = finite(name, value)
    if v <= 0:
        raise InvalidInputError(f"`{name}` must be > 0, got {v}")
    return v


def non_negative(name: str, value: float) -> float:
    v = finite(name, value)
    if v < 0:
        raise InvalidInputError(f"`{name}` must be >= 0, got {v}")
    return v
