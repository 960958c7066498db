"""Figures of the glitch study (matplotlib ``Figure`` objects, no pyplot)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..plotting import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .results import CircleResult, CompensationResult, ScenarioResult

_LABELS = {"none": "without friction", "static": "static map (Simulink linear region)", "gms": "GMS",
           "static_stiction": "static map, true stiction",
           "static_feedforward": "static-map feedforward", "gms_feedforward": "GMS feedforward",
           "static_feedforward_stiction": "stiction-map feedforward", "dob": "PID + disturbance observer"}


def plot_tracking_errors(result: "ScenarioResult", *, zoom: float | None = 4.0) -> "Figure":
    """Fig. 14 equivalent: tracking error of each model over the run (top) and the glitch
    ``e - e_lin`` around the first reversal (bottom, ``zoom`` seconds either side)."""
    fig, (ax0, ax1) = new_figure(2, 1, figsize=(8.0, 6.5))
    first = None
    for name, run in result.runs.items():
        ax0.plot(run.t, run.error * 1e6, lw=0.9, label=_LABELS.get(name, name))
        ev = result.metrics[name].events
        if ev and first is None:
            first = ev[0].time
    ax0.set_xlabel("time [s]")
    ax0.set_ylabel("tracking error [µm]")
    ax0.set_title("Tracking errors without and with friction models (paper Fig. 14)")
    if first is not None and zoom:
        for name, run in result.runs.items():
            m = (run.t >= first - zoom) & (run.t <= first + zoom)
            ax1.plot(run.t[m] - first, (run.error - result.baselines[name])[m] * 1e6, lw=1.0,
                     label=f"{_LABELS.get(name, name)}: {result.metrics[name].height * 1e6:.2f} µm")
        ax1.set_xlabel("time after reversal [s]")
        ax1.set_ylabel("glitch e - e_lin [µm]")
        ax1.legend(fontsize="small")
    for ax in (ax0, ax1):
        ax.grid(True, alpha=0.3)
    ax0.legend(fontsize="small")
    return fig


def plot_circle_polar(result: "CircleResult", *, scale_um: float | None = None) -> "Figure":
    """Ballbar-style polar plot: ``rho = offset + radial error`` in µm, so the quadrant glitches
    stand out as spikes on a circle (the offset is printed as the reference ring)."""
    fig, axes = new_figure(figsize=(6.5, 6.5))
    axes[0].remove()
    ax = fig.add_subplot(projection="polar")
    sel = (result.theta >= 0) & (result.theta <= 2 * np.pi)
    span = max(float(np.max(np.abs(e[sel]))) for e in result.radial_error.values()) * 1e6
    offset = scale_um if scale_um is not None else max(2.0 * span, 1e-3)
    th = np.linspace(0, 2 * np.pi, 361)
    ax.plot(th, np.full_like(th, offset), "k:", lw=0.8, label=f"nominal R = {result.radius * 1e3:g} mm")
    for name, er in result.radial_error.items():
        ax.plot(result.theta[sel], offset + er[sel] * 1e6, lw=1.0, label=_LABELS.get(name, name))
    ax.set_ylim(0.0, offset + 1.2 * span)
    ax.set_yticklabels([])
    ax.set_title(f"Circle test: radial error in µm (dotted ring = 0, drawn at {offset:.3g} µm)")
    ax.legend(fontsize="small", loc="lower left", bbox_to_anchor=(-0.1, -0.12))
    return fig


def plot_compensation(result: "CompensationResult", *, zoom: float = 4.0) -> "Figure":
    """Before/after compensation: glitch ``e - e_lin`` at the first reversal for each strategy
    (top) and the feedforward signals (bottom)."""
    fig, (ax0, ax1) = new_figure(2, 1, figsize=(8.0, 6.5), sharex=True)
    ev = result.metrics["none"].events
    t0 = ev[0].time if ev else 0.0
    for name, run in result.runs.items():
        m = (run.t >= t0 - zoom) & (run.t <= t0 + zoom)
        label = "no compensation" if name == "none" else _LABELS.get(name, name)
        (line,) = ax0.plot(run.t[m] - t0, (run.error - result.baseline)[m] * 1e6, lw=1.0,
                           label=f"{label}: {result.metrics[name].height * 1e6:.3f} µm")
        ff = result.feedforward.get(name)
        if ff is not None:
            ax1.plot(run.t[m] - t0, ff[m], lw=1.0, color=line.get_color(), label=_LABELS.get(name, name))
        if name == "none":
            ax1.plot(run.t[m] - t0, run.friction[m] / result.force_gain, "k--", lw=0.8, label="true friction / force_gain")
    ax0.set_ylabel("glitch e - e_lin [µm]")
    ax0.set_title("Friction compensation at a reversal")
    ax1.set_ylabel("feedforward [V]")
    ax1.set_xlabel("time after reversal [s]")
    for ax in (ax0, ax1):
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    return fig


__all__ = ["plot_tracking_errors", "plot_circle_polar", "plot_compensation"]
