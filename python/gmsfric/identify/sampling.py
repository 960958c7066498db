"""Sensor properties estimated from a record itself (shared by the identifiers): the position
resolution (encoder quantum or white noise) and the white-noise level of a smooth signal."""

from __future__ import annotations

from math import comb

import numpy as np
from numpy.typing import NDArray


def white_noise_level(x: NDArray[np.float64]) -> float:
    """Standard deviation of white noise on a signal that is smooth between samples: the robust
    scatter of second differences (kinks and steps are isolated, the median ignores them)."""
    if x.size < 3:
        return 0.0
    return 1.4826 * float(np.median(np.abs(np.diff(x, 2)))) / np.sqrt(6.0)


#: Steps below this fraction of a position's span are floating-point rounding, not encoder
#: counts (a 32-bit encoder over its whole range still moves 2.3e-10 of it per count).
ROUNDING_STEP = 1e-11


def smooth_noise_level(x: NDArray[np.float64]) -> float:
    """White-noise level of a signal whose smooth part may curve appreciably between samples
    (a sinusoid at a few hundred samples per cycle): the smallest of the robust scatters of the
    2nd, 3rd and 4th differences, each scaled to the noise's standard deviation.  White noise
    gives the same value at every order; a smooth signal's k-th difference shrinks by the
    per-sample phase step at every order, so its curvature no longer reads as noise."""
    x = np.asarray(x, dtype=float)
    out = []
    d = np.diff(x)
    for order in (2, 3, 4):
        d = np.diff(d)
        if d.size < 1:
            break
        # var of the k-th difference of white noise: C(2k, k) sigma^2
        out.append(1.4826 * float(np.median(np.abs(d))) / np.sqrt(comb(2 * order, order)))
    return min(out) if out else 0.0


def estimate_resolution(x: NDArray[np.float64]) -> float:
    """Position resolution: the encoder quantum (:func:`quantum`, steps down to
    ``ROUNDING_STEP`` of the span) or the white-noise level (:func:`smooth_noise_level`),
    whichever is larger; never below 1e-9 of the range.

    An unquantised record has no quantum: its smallest step is some short move at a reversal
    (a sampled sinusoid's ``A (1 - cos(2 pi / n))``), no resolution."""
    span = max(float(np.ptp(x)), 1e-300)
    return max(quantum(x, min_step=ROUNDING_STEP), smooth_noise_level(x), 1e-9 * span)


def plateau_resolution(x: NDArray[np.float64]) -> float:
    """The coarser resolution the static map's plateau search is tuned on: the smallest step
    above 1e-6 of the span or the 2nd-difference noise level, whichever is larger (never below
    1e-9 of the range).  It errs high (a fine encoder's count, a curving signal), which there only
    widens the velocity windows; the pre-sliding fit uses :func:`estimate_resolution`."""
    span = max(float(np.ptp(x)), 1e-300)
    dx = np.abs(np.diff(x))
    steps = dx[dx > 1e-6 * span]
    q = float(steps.min()) if steps.size else 0.0
    return max(q, white_noise_level(x), 1e-9 * span)


def quantum(x: NDArray[np.float64], *, min_step: float = 1e-6) -> float:
    """The encoder quantum (smallest step above ``min_step`` times the span, smaller steps taken
    for rounding of a file's digits), 0 for an unquantised signal (no step repeats: white noise
    or a smooth curve leaves no common step)."""
    span = max(float(np.ptp(x)), 1e-300)
    dx = np.abs(np.diff(x))
    # never below a few units in the last place of the values (float rounding of a conversion)
    tiny = max(min_step * span, 4.0 * np.finfo(float).eps * float(np.max(np.abs(x))))
    steps = dx[dx > tiny]
    if steps.size == 0:
        return 0.0
    sample = steps[: min(steps.size, 20000)]
    # the quantum divides every step: the smallest step, or the smallest difference of two step
    # sizes when the record never moves slower than several counts per sample (a fast triangle
    # wave moving 91 and 92 counts a sample shows its count only there)
    sizes = np.unique(sample)
    gaps = np.diff(sizes)
    gaps = gaps[gaps > tiny]
    q = min(float(sizes[0]), float(gaps.min()) if gaps.size else np.inf)
    ratio = sample / q
    if np.median(np.abs(ratio - np.round(ratio))) >= 0.05:
        return 0.0
    # the mean count size (the smallest step alone carries its rounding)
    return float(np.median(sample / np.round(ratio)))


__all__ = ["white_noise_level", "smooth_noise_level", "estimate_resolution", "plateau_resolution", "quantum"]
