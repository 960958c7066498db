"""Sensor properties estimated from a record itself (shared by the identifiers): the position
resolution (encoder quantum or white noise) and the white-noise level of a smooth signal."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def white_noise_level(x: NDArray[np.float64]) -> float:
    """Standard deviation of white noise on a signal that is smooth between samples: the robust
    scatter of second differences (kinks and steps are isolated, the median ignores them)."""
    if x.size < 3:
        return 0.0
    return 1.4826 * float(np.median(np.abs(np.diff(x, 2)))) / np.sqrt(6.0)


def estimate_resolution(x: NDArray[np.float64]) -> float:
    """Position resolution: the encoder quantum (smallest step) or the white-noise level,
    whichever is larger; never below 1e-9 of the range."""
    span = max(float(np.ptp(x)), 1e-300)
    dx = np.abs(np.diff(x))
    # steps below 1e-6 of the span are rounding of the file's decimal digits, not encoder counts
    steps = dx[dx > 1e-6 * span]
    quantum = float(steps.min()) if steps.size else 0.0
    return max(quantum, white_noise_level(x), 1e-9 * span)


def quantum(x: NDArray[np.float64]) -> float:
    """The encoder quantum (smallest step above rounding), 0 for an unquantised signal (no
    step repeats: white noise leaves no common step)."""
    span = max(float(np.ptp(x)), 1e-300)
    dx = np.abs(np.diff(x))
    steps = dx[dx > 1e-6 * span]
    if steps.size == 0:
        return 0.0
    q = float(steps.min())
    # a quantised signal moves in multiples of its quantum
    ratio = steps[: min(steps.size, 20000)] / q
    return q if np.median(np.abs(ratio - np.round(ratio))) < 0.05 else 0.0


__all__ = ["white_noise_level", "estimate_resolution", "quantum"]
