"""Figures of a loop run (matplotlib ``Figure`` objects, no pyplot)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .. import units as _units
from ..plotting import new_figure

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .residuals import Finding
    from .results import LoopResult


def plot_steps(result: "LoopResult") -> "Figure":
    """Estimation and validation error of the baseline and after each added effect."""
    fig, (ax,) = new_figure(figsize=(7.0, 4.0))
    labels = ["baseline"] + [s.effect for s in result.steps if s.accepted]
    est = [result.baseline_errors[0]] + [s.estimation_error_pct for s in result.steps if s.accepted]
    val = [result.baseline_errors[1]] + [s.validation_error_pct for s in result.steps if s.accepted]
    x = np.arange(len(labels))
    ax.bar(x - 0.2, est, 0.4, label="estimation")
    ax.bar(x + 0.2, val, 0.4, label="validation")
    ax.set_xticks(x, labels, rotation=20, ha="right", fontsize="small")
    ax.set_ylabel("relative force error [%]")
    ax.legend()
    ax.grid(True, axis="y", alpha=0.3)
    return fig


def plot_fit(result: "LoopResult") -> "Figure":
    """Measured force against the baseline and final predictions on the held-out rows."""
    sp = result.split
    fig, axes = new_figure(2, 1, figsize=(9.0, 6.0), sharex=True)
    rows = sp.val_rows
    t = sp.val.rows["t"][rows]
    y = sp.val.y[rows]
    yb = result.baseline.predict(sp.val)[rows]
    yf = result.final.predict(sp.val)[rows]
    axes[0].plot(t, y, "k", lw=0.8, label="measured")
    axes[0].plot(t, yb, lw=0.8, label="baseline")
    axes[0].plot(t, yf, lw=0.8, label="final")
    fu = _units.display_unit("force", result.rotary)
    axes[0].set_ylabel(f"force [{fu}]")
    axes[0].legend(fontsize="small")
    axes[1].plot(t, y - yb, ".", ms=1.5, label="baseline residual")
    axes[1].plot(t, y - yf, ".", ms=1.5, label="final residual")
    axes[1].set_ylabel(f"residual [{fu}]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig


def plot_closed_loop_runs(sims: dict[tuple[str, str], Any], runs: dict[str, Any], *, rotary: bool = False) -> "Figure":
    """Closed-loop simulations against the measurement: position error and force."""
    # tracking differences are small: micrometres (microradians) rather than the display unit
    err_unit = "µrad" if rotary else "µm"
    err_scale = 1e6
    names = sorted({r for _, r in sims})
    fig, axes = new_figure(2, max(1, len(names)), figsize=(6.0 * max(1, len(names)), 6.0))
    axes = axes.reshape(2, -1)
    for j, rn in enumerate(names):
        d = runs[rn].data
        g = d.gain if d.gain is not None else 1.0
        axes[1, j].plot(d.t, d.force, "k", lw=0.6, label="measured")
        for (m, r), res in sims.items():
            if r != rn:
                continue
            axes[0, j].plot(d.t, (res.position - d.position) * err_scale, lw=0.7, label=m)
            axes[1, j].plot(d.t, g * res.command, lw=0.6, label=m)
        axes[0, j].set_title(rn, fontsize="medium")
        axes[0, j].set_ylabel(f"simulated - measured position [{err_unit}]")
        axes[1, j].set_ylabel(f"force [{_units.display_unit('force', rotary)}]")
        axes[1, j].set_xlabel("time [s]")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="small")
    return fig


def plot_open_loop(runs: dict[tuple[str, str], tuple[Any, Any]], *, rotary: bool = False) -> "Figure":
    """Open-loop simulations (position from the measured command) against the measured position."""
    unit = _units.display_unit("position", rotary)
    k = 1.0 / _units.factor(unit, "position", rotary=rotary)
    names = sorted({r for _, r in runs})
    fig, axes = new_figure(2, len(names), figsize=(6.0 * len(names), 6.0), sharex=False)
    axes = axes.reshape(2, -1)
    for j, rn in enumerate(names):
        shown = False
        for (m, r), (data, res) in runs.items():
            if r != rn or res.position is None:
                continue
            if not shown:
                axes[0, j].plot(data.t, k * data.position, "k", lw=0.8, label="measured")
                shown = True
            axes[0, j].plot(data.t, k * res.position, lw=0.7, label=m)
            axes[1, j].plot(data.t, k * (res.position - data.position), lw=0.7, label=m)
        axes[0, j].set_title(f"{rn}: open loop", fontsize="medium")
        axes[0, j].set_ylabel(f"position [{unit}]")
        axes[1, j].set_ylabel(f"simulated - measured [{unit}]")
        axes[1, j].set_xlabel("time [s]")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="small")
    return fig


def plot_finding(f: "Finding", *, rotary: bool = False) -> "Figure":
    """Figure of one residual test: residual against the variable with binned means, or the
    cross-correlation / coherence / position periodogram (display units of a linear or rotary axis)."""
    fu = _units.display_unit("force", rotary)
    extra = "periodogram" in f.curve
    fig, axes = new_figure(1, 2 if extra else 1, figsize=(10.0 if extra else 6.5, 4.0))
    ax = axes[0]
    c = f.curve
    if "centres" in c:
        x = c["x"]
        quantity, label = {"velocity": ("velocity", "velocity"), "position": ("position", "position"), "position_odd": ("position", "position"),
                           "time": ("time", "time"), "time_even": ("time", "time"), "acceleration": ("acceleration", "acceleration")}.get(f.variable, ("", ""))
        if quantity:
            scale, shown = _units.to_display(1.0, quantity, rotary)
            unit = f"{label} [{shown}]"
        else:  # reversal: log10 of a distance in SI
            scale, unit = 1.0, f"log10 distance since reversal [{_units.si_unit('position', rotary)}]"
        step = max(1, x.size // 4000)
        ax.plot(x[::step] * scale, c["y"][::step], ".", ms=1.5, alpha=0.3, color="0.5")
        ax.plot(c["centres"] * scale, c["means"], "o-", color="C3", label="binned mean")
        ax.set_xlabel(unit)
        ax.set_ylabel("residual" + (" × sign(qd)" if f.variable in ("position_odd", "time", "reversal") else "") + f" [{fu}]")
        lim = np.nanmax(np.abs(c["means"])) * 4 + 1e-9
        ax.set_ylim(-lim, lim)
    elif "xcorr" in c:
        ax.plot(c["lags_s"] * 1e3, c["xcorr"], "o-")
        ax.set_xlabel("lag of predicted force [ms]")
        ax.set_ylabel("cross-correlation [1]")
    elif "coherence" in c:
        ax.plot(c["f"], c["coherence"], label="coherence(residual, qdd)")
        ax2 = ax.twinx()
        ax2.semilogy(c["psd_f"], c["psd"], color="C1", lw=0.8)
        ax2.set_ylabel(f"residual PSD [({fu})²/Hz]")
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel("coherence [1]")
    ax.set_title(f"{f.variable}: stat={f.statistic:.3g}, z={f.z:.1f}{' (significant)' if f.significant else ''}", fontsize="medium")
    ax.grid(True, alpha=0.3)
    if extra:
        k, ku = _units.to_display(1.0, "inverse_position", rotary)
        axes[1].semilogy(c["spatial_freq"] * k, c["periodogram"])
        axes[1].set_xlabel(f"spatial frequency [{ku}]")
        axes[1].set_ylabel(f"periodogram [({fu})²]")
        axes[1].set_title("residual in the position domain", fontsize="medium")
        axes[1].grid(True, alpha=0.3)
    return fig


def figures(result: "LoopResult") -> dict[str, "Figure"]:
    """Every figure of a loop run by file stem: the residual tests, the steps, the held-out fit
    and, when the run was simulated in closed loop, the simulations against the measurement."""
    figs: dict[str, "Figure"] = {}
    for stage, fl in result.findings.items():
        for f in fl:
            figs[f"residual_{stage}_{f.variable}"] = plot_finding(f, rotary=result.rotary)
    figs["steps"] = plot_steps(result)
    figs["fit_validation"] = plot_fit(result)
    if result.closed_loop_runs:
        runs = {"estimation": result.split.est, "validation": result.split.val}
        figs["closed_loop"] = plot_closed_loop_runs(result.closed_loop_runs, runs, rotary=result.rotary)
    return figs


__all__ = ["figures", "plot_steps", "plot_fit", "plot_closed_loop_runs", "plot_finding"]
