"""Matplotlib figures.  Every function returns a ``Figure`` the caller can ``savefig``; pyplot is
not used, so nothing pops up and the functions work headless."""

from __future__ import annotations

from typing import TYPE_CHECKING, Optional, Sequence

import numpy as np
from matplotlib.figure import Figure

if TYPE_CHECKING:  # pragma: no cover
    from .models import FrictionModel, StaticFriction
    from .system import ClosedLoopResult


def new_figure(nrows: int = 1, ncols: int = 1, *, figsize: tuple[float, float] = (7.0, 4.5), sharex: bool = False) -> tuple[Figure, np.ndarray]:
    """A figure and a flat array of axes, without touching pyplot's global state."""
    fig = Figure(figsize=figsize, layout="constrained")
    axes = fig.subplots(nrows, ncols, sharex=sharex, squeeze=False)
    return fig, axes.ravel()


def plot_closed_loop(result: "ClosedLoopResult", fig: Optional[Figure] = None, *, label: str | None = None) -> Figure:
    """Position and reference, tracking error, drive command and friction force against time."""
    if fig is None:
        fig, axes = new_figure(4, 1, figsize=(7.5, 8.0), sharex=True)
    else:
        axes = np.asarray(fig.axes)
    t = result.t
    axes[0].plot(t, result.reference * 1e3, "k--", lw=0.8, label="reference" if label is None else None)
    axes[0].plot(t, result.position * 1e3, lw=1.0, label=label or "position")
    axes[0].set_ylabel("position [mm]")
    axes[1].plot(t, result.error * 1e6, lw=0.8, label=label)
    axes[1].set_ylabel("error [µm]")
    axes[2].plot(t, result.command, lw=0.8, label=label)
    axes[2].set_ylabel("command")
    axes[3].plot(t, result.friction, lw=0.8, label=label)
    axes[3].set_ylabel("friction [N]")
    axes[3].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    if label is not None:
        axes[1].legend(loc="best", fontsize="small")
    return fig


def plot_friction_map(models: Sequence["StaticFriction"], labels: Sequence[str], v_max: float, *, data: tuple[np.ndarray, np.ndarray] | None = None) -> Figure:
    """Static friction maps ``F(v)`` on a symmetric log-spaced velocity axis, optionally with
    measured (velocity, force) points."""
    fig, (ax,) = new_figure()
    v_pos = np.logspace(np.log10(v_max) - 5, np.log10(v_max), 400)
    v = np.concatenate((-v_pos[::-1], v_pos))
    for m, lab in zip(models, labels):
        ax.plot(v * 1e3, m.force(v), label=lab)
    if data is not None:
        ax.plot(data[0] * 1e3, data[1], "k.", ms=4, label="measured")
    ax.set_xscale("symlog", linthresh=max(v_max * 1e-2, 1e-9) * 1e3)
    ax.set_xlabel("velocity [mm/s]")
    ax.set_ylabel("friction force [N]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def plot_hysteresis(x: np.ndarray, f: np.ndarray, *, virgin: tuple[np.ndarray, np.ndarray] | None = None, title: str = "") -> Figure:
    """Force against displacement (pre-sliding hysteresis loops), optionally with a virgin curve."""
    fig, (ax,) = new_figure()
    ax.plot(x * 1e6, f, lw=0.9, label="friction force")
    if virgin is not None:
        ax.plot(virgin[0] * 1e6, virgin[1], "r--", lw=1.2, label="virgin curve")
    ax.set_xlabel("displacement [µm]")
    ax.set_ylabel("friction force [N]")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    return fig
