"""Figures of the identification steps (matplotlib ``Figure`` objects, no pyplot).

:func:`figures` gives the figures of an :class:`~gmsfric.identify.IdentificationResult` by file
stem (``<model>_<label>``); the compute modules import no matplotlib.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import numpy as np
from numpy.typing import NDArray

from ..models import simulate_friction
from ..plotting import new_figure
from .frf import FRF, PLANT_NAMES, plant_response, zoh_factor
from .presliding import VirginCurve, virgin_model
from .static_map import NAMES, static_map_curve

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from ..system import Plant
    from .results import IdentificationResult


def _rate_parts(unit: str) -> tuple[str, str]:
    """``("mm", "s")`` for ``"mm/s"``; ``("", "")`` when the unit is not a plain quotient."""
    num, sep, den = unit.partition("/")
    return (num.strip(), den.strip()) if sep and "/" not in den and "(" not in unit else ("", "")


def _frequency_unit(time_unit: str) -> str:
    return "Hz" if time_unit == "s" else f"1/{time_unit}"


def plot_static_map(res: "IdentificationResult") -> dict[str, "Figure"]:
    """Fit and residuals (cf. paper Fig. 5) and, for a raw run, the plateaus found (Fig. 4)."""
    v, F, se = res.data["velocity"], res.data["force"], res.data["force_stderr"]
    p = [res.value(k) for k in NAMES]
    fu, vu = res.units.get("fc", ""), res.units.get("vs", "")
    figs = {}
    fig, (ax, axr) = new_figure(2, 1, figsize=(7.0, 6.0), sharex=True)
    vmax = np.abs(v).max()
    vmin = np.abs(v[v != 0]).min()
    grid = np.geomspace(vmin / 3, vmax * 1.1, 300)
    grid = np.concatenate((-grid[::-1], grid))
    ax.plot(grid, static_map_curve(grid, *p), "C0-", label="eq. 2 fit")
    ax.errorbar(v, F, yerr=se if np.any(se != 1) else None, fmt="k.", ms=4, label="plateau averages")
    ax.set_xscale("symlog", linthresh=vmin)
    ax.set_ylabel(f"force [{fu}]")
    ax.legend(fontsize="small")
    ax.set_title("static friction map (cf. paper Fig. 5)")
    axr.plot(v, F - static_map_curve(v, *p), "k.", ms=4)
    axr.axhline(0, color="C0", lw=0.8)
    axr.set_ylabel(f"residual [{fu}]")
    axr.set_xlabel(f"velocity [{vu}]")
    for a in (ax, axr):
        a.grid(True, alpha=0.3)
    figs["static_map_fit"] = fig
    if "t" in res.data:
        xu, tu = _rate_parts(vu)
        fig2, (a1, a2) = new_figure(2, 1, figsize=(8.0, 5.5), sharex=True)
        t = res.data["t"]
        a1.plot(t, res.data["position"], lw=0.8)
        a2.plot(t, res.data["raw_force"], lw=0.5, color="0.6")
        kf = res.data.get("to_user", {}).get("force", 1.0)  # the plateaus were found in SI
        for pl in res.data["plateaus"]:
            a2.plot(t[[pl.start, pl.stop - 1]], [pl.force * kf, pl.force * kf], "C1-", lw=2)
        for pl in res.data["rejected"]:
            a2.axvspan(t[pl.start], t[pl.stop - 1], color="r", alpha=0.15)
        a1.set_ylabel(f"position [{xu or 'data unit'}]")
        a2.set_ylabel(f"force [{fu}] (kept plateaus; rejected shaded)")
        a2.set_xlabel(f"time [{tu or 'data unit'}]")
        figs["static_map_plateaus"] = fig2
    return figs


def plot_presliding(res: "IdentificationResult") -> dict[str, "Figure"]:
    """Virgin curve with its knots (cf. paper Fig. 7) and the fitted hysteresis (Fig. 6), in the
    data's units (the fit ran in SI)."""
    vc: VirginCurve = res.data["virgin"]
    f = res.data.get("to_si", {"position": 1.0, "force": 1.0, "time": 1.0})
    kx, kf, kt = f["position"], f["force"], f["time"]
    model = res.data.get("model")
    k = np.asarray(model.k) if model is not None else np.array([res.value(f"k{i + 1}") for i in range(res.info["n_blocks"])]) * kf / kx
    w = np.asarray(model.break_forces) if model is not None else np.array([res.value(f"w{i + 1}") for i in range(res.info["n_blocks"])]) * kf
    d = w / k
    nb = k.size
    pu = res.data.get("force_unit", res.units.get("w1", ""))
    xu = res.data.get("position_unit", "")
    tu = res.data.get("time_unit", "")
    fig, (ax, axl) = new_figure(1, 2, figsize=(11.0, 4.5))
    uu = np.linspace(0, vc.u_bin.max(), 400)
    ax.plot(vc.u / kx, vc.g / kf, ",", color="0.7", label="Masing branches (halved, shifted)")
    ax.plot(vc.u_bin / kx, vc.g_bin / kf, "k.", ms=4, label="binned virgin curve")
    ax.plot(uu / kx, virgin_model(uu, k, d) / kf, "C0-", label=f"{nb} blocks")
    ax.plot(d / kx, virgin_model(d, k, d) / kf, "rs", ms=5, label="knots")
    ax.set_xlabel(f"displacement [{xu}]")
    ax.set_ylabel(f"force [{pu}]")
    ax.set_title("virgin curve with knots (cf. paper Fig. 7)")
    ax.legend(fontsize="small")
    ul = np.geomspace(vc.u_bin.min(), vc.u_bin.max(), 400)
    axl.semilogx(vc.u_bin / kx, vc.g_bin / kf, "k.", ms=4)
    axl.semilogx(ul / kx, virgin_model(ul, k, d) / kf, "C0-")
    for di in d:
        axl.axvline(di / kx, color="r", lw=0.6, ls=":")
    axl.set_xlabel(f"displacement [{xu}] (log)")
    axl.set_ylabel(f"force [{pu}]")
    for a in (ax, axl):
        a.grid(True, alpha=0.3)
    figs = {"presliding_virgin": fig}
    if model is not None and "t" in res.data:
        t, x, F = res.data["t"], res.data["x"], res.data["F"]
        sim = simulate_friction(model, t, x) + res.data.get("force_offset", 0.0)
        fig2, (a1, a2) = new_figure(2, 1, figsize=(7.0, 7.0))
        a1.plot(x / kx, F / kf, ",", color="0.5", label="measured")
        a1.plot(x / kx, sim / kf, "C0-", lw=0.8, label="identified blocks")
        a1.set_xlabel(f"position [{xu}]")
        a1.set_ylabel(f"force [{pu}]")
        a1.legend(fontsize="small")
        a1.set_title("pre-sliding hysteresis (cf. paper Fig. 6)")
        a2.plot(t / kt, (F - sim) / kf, "k-", lw=0.5)
        a2.set_xlabel(f"time [{tu}]")
        a2.set_ylabel(f"residual [{pu}]")
        for a in (a1, a2):
            a.grid(True, alpha=0.3)
        figs["presliding_hysteresis"] = fig2
    return figs


def bode_figure(
    curves: list[tuple[str, NDArray[np.float64], NDArray[np.complex128], dict[str, Any]]],
    coherence: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    title: str = "",
    *,
    magnitude_unit: str = "m/V",
    frequency_unit: str = "Hz",
) -> "Figure":
    """Bode magnitude/phase (and coherence) of several responses ``(label, f, H, style)``."""
    n = 3 if coherence is not None else 2
    fig, axes = new_figure(n, 1, figsize=(7.0, 7.5 if n == 3 else 6.0), sharex=True)
    for label, f, H, style in curves:
        axes[0].loglog(f, np.abs(H), label=label, **style)
        axes[1].semilogx(f, np.degrees(np.unwrap(np.angle(H))), label=label, **style)
    axes[0].set_ylabel(f"magnitude [{magnitude_unit}]")
    axes[1].set_ylabel("phase [deg]")
    if coherence is not None:
        axes[2].semilogx(coherence[0], coherence[1], "k-", lw=0.8)
        axes[2].set_ylabel("coherence [1]")
        axes[2].set_ylim(0, 1.05)
    axes[-1].set_xlabel(f"frequency [{frequency_unit}]")
    axes[0].legend(fontsize="small")
    axes[0].set_title(title)
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
    return fig


def plot_plant(res: "IdentificationResult") -> dict[str, "Figure"]:
    """Measured FRF with the eq. 1 fit and the coherence (cf. paper Fig. 3)."""
    frf: FRF = res.data["frf"].select(0.0, float(res.data["fit_f"].max()))
    p = [res.value(k) for k in PLANT_NAMES]
    T = float(res.info.get("zoh_dt", 0.0))
    fig = bode_figure(
        [("measured H1", frf.f, frf.H, {"color": "0.5", "lw": 0.8}), ("eq. 1 fit", frf.f, plant_response(frf.f, *p, T), {"color": "C0", "lw": 1.5})],
        (frf.f, frf.coherence),
        title="FRF and plant fit (cf. paper Fig. 3)",
        magnitude_unit=f"{res.data.get('output_unit', 'm')}/{res.data.get('input_unit', 'V')}",
        frequency_unit=_frequency_unit(res.units.get("delay", "s")),
    )
    return {"plant_bode": fig}


def plot_revision(res: "IdentificationResult") -> dict[str, "Figure"]:
    """The combined model's FRF before (cf. Figs. 10/12) and after (Figs. 11/13) the revision."""
    meas_all: FRF = res.data["measured"]
    fmax = float(meas_all.f[res.data["sel"]].max())
    keep = meas_all.f <= fmax
    meas = meas_all.select(0.0, fmax)
    p0: "Plant" = res.data["original_plant"]
    f = meas.f
    orig_H, rev_H = res.data["original_combined"].H[keep], res.data["revised_combined"].H[keep]
    name = res.info.get("friction") or "no friction"
    original = ("original model", f, p0.frequency_response(f) * zoh_factor(f, meas.dt), {"color": "k", "ls": "--", "lw": 1.0})
    measured = ("actual measurement", f, meas.H, {"color": "0.5", "lw": 0.8})
    fig1 = bode_figure([measured, original, (f"combined model ({name})", f, orig_H, {"color": "C3", "lw": 1.2})],
                       (f, meas.coherence), title=f"combined model, {name} (cf. Figs. 10/12)")
    fig2 = bode_figure([measured, original, (f"revised model ({name})", f, rev_H, {"color": "C2", "lw": 1.2})],
                       (f, meas.coherence), title=f"revised model, {name} (cf. Figs. 11/13)")
    return {"revised_plant_combined": fig1, "revised_plant_revised": fig2}


PLOTTERS: dict[str, Callable[["IdentificationResult"], dict[str, "Figure"]]] = {
    "static_map": plot_static_map,
    "presliding": plot_presliding,
    "plant": plot_plant,
    "revised_plant": plot_revision,
}


def figures(res: "IdentificationResult") -> dict[str, "Figure"]:
    """The figures of ``res`` by file stem (none for a model without a plotter)."""
    plotter = PLOTTERS.get(res.model)
    return {} if plotter is None else plotter(res)


__all__ = ["figures", "bode_figure", "plot_static_map", "plot_presliding", "plot_plant", "plot_revision", "PLOTTERS"]
