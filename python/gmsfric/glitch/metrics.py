"""Glitch detection at motion reversals: peak, duration and area.

Definitions (also in ``docs/glitch.md``)
----------------------------------------
A *reversal* is a sign change of the reference velocity (``numpy.gradient`` of the reference).
Around each reversal at ``t_r`` the *window* is ``[t_r - pre, t_r + post]``.

* ``glitch signal`` ``g(t) = e(t) - e_lin(t)``: the tracking error minus the *baseline*, the
  tracking error of the same loop without friction (the linear error).  Without a baseline the
  error at the reversal instant is subtracted, i.e. ``g`` is the spike height above the error at
  ``t_r``.
* ``raw_peak_error`` = ``max |e|`` over the glitch (the samples of the window where
  ``|g| >= fraction * height``): the raw tracking error at the spike, what the paper's Fig. 14
  plots.  Without a glitch (``height == 0``, e.g. the frictionless run) it is ``|e(t_r)|``.
* ``height`` = ``max |g|`` in the window (``signed_height`` keeps its sign): the glitch itself.
  This is the *peak error at the reversal* of the CLI's JSON (``peak_error_m``).
* ``duration`` = total time in the window during which ``|g| >= fraction * height``
  (``fraction = 0.5``: the full width at half height of the spike).
* ``area`` = ``integral |g| dt`` over the window (m s).

A PI(D) loop integrates a friction step away with ``integral g dt = dF / (force_gain ki)`` whatever
the friction model: the *area* of a glitch is fixed by the friction jump; a model that spreads the
force change over pre-sliding gives a lower, longer glitch than one that switches abruptly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import as_array, same_length
from ..errors import InvalidInputError


@dataclass(frozen=True)
class GlitchEvent:
    """Metrics of one reversal.

    Attributes
    ----------
    time : float
        Reversal instant (s).
    direction : int
        +1 if the reference velocity goes from negative to positive, -1 otherwise.
    raw_peak_error : float
        ``max |e|`` over the glitch, ``|e(t_r)|`` without one (m).
    height : float
        ``max |g|`` in the window (m).
    signed_height : float
        ``g`` at its largest magnitude (m).
    peak_time : float
        Time of that extremum after the reversal (s).
    duration : float
        Time with ``|g| >= fraction * height`` (s).
    area : float
        ``integral |g| dt`` over the window (m s).
    """

    time: float
    direction: int
    raw_peak_error: float
    height: float
    signed_height: float
    peak_time: float
    duration: float
    area: float

    def to_dict(self) -> dict[str, float]:
        """Plain-JSON dict with SI unit suffixes."""
        return {
            "time_s": self.time,
            "direction": self.direction,
            "peak_error_m": self.height,
            "signed_peak_error_m": self.signed_height,
            "raw_peak_error_m": self.raw_peak_error,
            "peak_delay_s": self.peak_time,
            "duration_s": self.duration,
            "area_m_s": self.area,
        }


@dataclass(frozen=True)
class GlitchReport:
    """All reversals of one run, with the worst values over them.

    Attributes
    ----------
    events : list of GlitchEvent
    raw_peak_error, height, duration, area : float
        Maxima over the events (0 when there is no reversal).
    """

    events: Sequence[GlitchEvent] = field(default_factory=tuple)

    @property
    def raw_peak_error(self) -> float:
        return max((e.raw_peak_error for e in self.events), default=0.0)

    @property
    def height(self) -> float:
        return max((e.height for e in self.events), default=0.0)

    @property
    def duration(self) -> float:
        return max((e.duration for e in self.events), default=0.0)

    @property
    def area(self) -> float:
        return max((e.area for e in self.events), default=0.0)

    def to_dict(self) -> dict[str, object]:
        """``{"peak_error_m" (= height), "raw_peak_error_m", "duration_s", "area_m_s", "reversals": [...]}``."""
        return {
            "peak_error_m": self.height,
            "raw_peak_error_m": self.raw_peak_error,
            "duration_s": self.duration,
            "area_m_s": self.area,
            "reversals": [e.to_dict() for e in self.events],
        }


def find_reversals(t: ArrayLike, reference: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Instants where the reference velocity changes sign.

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing.
    reference : array_like
        Reference position (m) at ``t``.

    Returns
    -------
    times : ndarray
        Reversal instants (s), linearly interpolated between samples.
    directions : ndarray of int
        +1 for a reversal from negative to positive velocity, -1 otherwise.
    """
    t_arr = as_array("t", t, min_len=3)
    r = as_array("reference", reference, min_len=3)
    same_length("reference", r, "t", t_arr.size)
    if np.any(np.diff(t_arr) <= 0):
        raise InvalidInputError("`t` must be strictly increasing")
    v = np.gradient(r, t_arr)
    scale = np.max(np.abs(v))
    if scale == 0:
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    s = np.where(np.abs(v) <= 1e-12 * scale, 0.0, np.sign(v))
    # carry the last non-zero sign over exact zeros so a touch of zero is one reversal
    nz = np.flatnonzero(s)
    if nz.size < 2:
        return np.zeros(0), np.zeros(0, dtype=np.int64)
    sn = s[nz]
    idx = np.flatnonzero(sn[1:] != sn[:-1])
    times, dirs = [], []
    for i in idx:
        a, b = nz[i], nz[i + 1]
        va, vb = v[a], v[b]
        times.append(t_arr[a] + (t_arr[b] - t_arr[a]) * va / (va - vb))
        dirs.append(int(np.sign(vb)))
    return np.asarray(times), np.asarray(dirs, dtype=np.int64)


def glitch_metrics(
    t: ArrayLike,
    error: ArrayLike,
    reference: ArrayLike,
    *,
    baseline: ArrayLike | None = None,
    window: tuple[float, float] | None = None,
    fraction: float = 0.5,
    reversals: ArrayLike | None = None,
) -> GlitchReport:
    """Peak, height, duration and area of the error at each reversal of ``reference``.

    Parameters
    ----------
    t : array_like
        Sample times (s), strictly increasing.
    error : array_like
        Tracking error ``reference - position`` (m).
    reference : array_like
        Reference position (m); its velocity reversals are the events.
    baseline : array_like, optional
        Frictionless (linear) tracking error of the same loop (m); ``g = error - baseline``.
        Without it ``g`` is the error minus its value at the reversal instant.
    window : (float, float), optional
        ``(pre, post)`` seconds around each reversal.  Default: ``pre = 0.1 P``,
        ``post = 0.25 P`` with ``P`` the shortest time between reversals (or the record length);
        ``pre`` covers the friction change a linear-region static map starts before the reversal.
    fraction : float
        Level, relative to the height, above which ``|g|`` counts towards the duration (0..1).
    reversals : array_like, optional
        Reversal instants to use instead of detecting them from ``reference``.

    Returns
    -------
    GlitchReport
    """
    t_arr = as_array("t", t, min_len=3)
    e = as_array("error", error, min_len=3)
    same_length("error", e, "t", t_arr.size)
    if baseline is not None:
        base = as_array("baseline", baseline)
        same_length("baseline", base, "t", t_arr.size)
    else:
        base = None
    fraction = float(fraction)
    if not 0.0 < fraction < 1.0:
        raise InvalidInputError(f"`fraction` must be in (0, 1), got {fraction}")
    if reversals is None:
        times, dirs = find_reversals(t_arr, reference)
    else:
        times = np.atleast_1d(as_array("reversals", reversals))
        r = as_array("reference", reference)
        v = np.gradient(r, t_arr)
        dirs = np.array([int(np.sign(np.interp(tr + 1e-9, t_arr, v)) or 1) for tr in times], dtype=np.int64)
    if window is None:
        span = np.min(np.diff(times)) if times.size > 1 else t_arr[-1] - t_arr[0]
        pre, post = 0.1 * span, 0.25 * span
    else:
        try:
            pre, post = (float(w) for w in window)
        except (TypeError, ValueError):
            raise InvalidInputError(f"`window` must be (pre, post) seconds, got {window!r}") from None
        if pre < 0 or post <= 0 or not (np.isfinite(pre) and np.isfinite(post)):
            raise InvalidInputError(f"`window` must have pre >= 0 and post > 0, got {window!r}")
    events = []
    dt = np.gradient(t_arr)
    for tr, d in zip(times, dirs):
        m = (t_arr >= tr - pre) & (t_arr <= tr + post)
        if np.count_nonzero(m) < 2:
            continue
        if base is not None:
            g = e[m] - base[m]
        else:
            g = e[m] - np.interp(tr, t_arr, e)
        i = int(np.argmax(np.abs(g)))
        h = float(abs(g[i]))
        above = np.abs(g) >= fraction * h
        dur = float(np.sum(dt[m][above])) if h > 0 else 0.0
        peak_err = float(np.max(np.abs(e[m][above]))) if h > 0 else float(abs(np.interp(tr, t_arr, e)))
        events.append(
            GlitchEvent(
                time=float(tr),
                direction=int(d),
                raw_peak_error=peak_err,
                height=h,
                signed_height=float(g[i]),
                peak_time=float(t_arr[m][i] - tr),
                duration=dur,
                area=float(np.sum(np.abs(g) * dt[m])),
            )
        )
    return GlitchReport(tuple(events))


__all__ = ["GlitchEvent", "GlitchReport", "find_reversals", "glitch_metrics"]
