"""Text table and figures of a loop run."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..plotting import new_figure
from .residuals import plot_finding

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .select import LoopResult


def format_table(result: "LoopResult") -> str:
    """Before/after table: baseline, every tested effect, final model, unexplained structure."""
    d = result.as_dict()
    lines = [f"estimation: {d['estimation']}    validation: {d['validation']}", ""]
    lines.append(f"{'step':<36}{'est %':>8}{'val %':>8}  decision")
    b = d["baseline"]
    lines.append(f"baseline: {b['model']}")
    lines.append(f"{'baseline':<36}{b['estimation_error_pct']:>8.3f}{b['validation_error_pct']:>8.3f}")
    al = d.get("alignment") or {}
    for a in al.get("tests", []):
        lines.append(f"  {'sampling hold (+' + format(al['sampling_hold_s'] * 1e3, '.3g') + ' ms), after r' + str(a['after_round']):<34}{a['estimation_error_pct']:>8.3f}{a['validation_error_pct']:>8.3f}  "
                     f"{'APPLIED (alignment, not an effect)' if a['applied'] else 'not applied'} t = {a['t_heldout']}")
    for s in d["steps"]:
        e = "   n/a" if s["estimation_error_pct"] is None else f"{s['estimation_error_pct']:8.3f}"
        v = "   n/a" if s["validation_error_pct"] is None else f"{s['validation_error_pct']:8.3f}"
        mark = "ADDED " if s["accepted"] else "      "
        lines.append(f"  r{s['round']} {s['effect']:<31}{e:>8}{v:>8}  {mark}{s['reason']}")
    f = d["final"]
    lines.append("")
    lines.append(f"{'final: ' + (', '.join(f['effects']) or 'no effect added'):<36}{f['estimation_error_pct']:>8.3f}{f['validation_error_pct']:>8.3f}")
    lines.append(f"before -> after: estimation {b['estimation_error_pct']:.3f} -> {f['estimation_error_pct']:.3f} %, validation {b['validation_error_pct']:.3f} -> {f['validation_error_pct']:.3f} %")
    lines.append("final parameters (value ± 1 std):")
    for k, p in f["parameters"].items():
        std = "" if p["std"] is None else f" ± {p['std']:.3g}"
        lines.append(f"  {k:<24}{p['value']:.6g}{std}")
    if d["unexplained"]:
        lines.append("unexplained residual structure:")
        for u in d["unexplained"]:
            lines.append(f"  {u['run']}: depends on {u['variable']} (z = {u['z']}), tried: {', '.join(u['candidates_tried']) or 'nothing applicable'}")
    else:
        lines.append("unexplained residual structure: none significant")
    if d.get("closed_loop"):
        lines.append("closed-loop simulation errors (%): position / velocity / acceleration / force")
        for m, runs in d["closed_loop"].items():
            for r, e in runs.items():
                lines.append(f"  {m:<9}{r:<28}{e['position_pct']:.4f} / {e['velocity_pct']:.3f} / {e['acceleration_pct']:.2f} / {e['force_pct']:.2f}")
    return "\n".join(lines)


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
    axes[0].set_ylabel("force [N]")
    axes[0].legend(fontsize="small")
    axes[1].plot(t, y - yb, ".", ms=1.5, label="baseline residual")
    axes[1].plot(t, y - yf, ".", ms=1.5, label="final residual")
    axes[1].set_ylabel("residual [N]")
    axes[1].set_xlabel("time [s]")
    axes[1].legend(fontsize="small")
    for ax in axes:
        ax.grid(True, alpha=0.3)
    return fig


def plot_closed_loop_runs(sims: dict[tuple[str, str], Any], runs: dict[str, Any]) -> "Figure":
    """Closed-loop simulations against the measurement: position error and force."""
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
            axes[0, j].plot(d.t, (res.position - d.position) * 1e6, lw=0.7, label=m)
            axes[1, j].plot(d.t, g * res.command, lw=0.6, label=m)
        axes[0, j].set_title(rn, fontsize="medium")
        axes[0, j].set_ylabel("simulated - measured position [µm]")
        axes[1, j].set_ylabel("force [N]")
        axes[1, j].set_xlabel("time [s]")
        for ax in axes[:, j]:
            ax.grid(True, alpha=0.3)
            ax.legend(fontsize="small")
    return fig


def save_figures(result: "LoopResult", directory: str | Path, sims: dict[tuple[str, str], Any] | None = None) -> list[Path]:
    """Write every figure of the run as PNG into ``directory``; returns the paths."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []

    def save(fig: "Figure", name: str) -> None:
        p = out / name
        fig.savefig(p, dpi=110)
        paths.append(p)

    for stage, fl in result.findings.items():
        for f in fl:
            save(plot_finding(f), f"residual_{stage}_{f.variable}.png")
    save(plot_steps(result), "steps.png")
    save(plot_fit(result), "fit_validation.png")
    if sims:
        runs = {"estimation": result.split.est, "validation": result.split.val}
        runs = {k: v for k, v in runs.items()}
        save(plot_closed_loop_runs(sims, runs), "closed_loop.png")
    return paths
