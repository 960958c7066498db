"""``gmsfric demo``: a tour on the example data shipped inside the package.

1. Static friction map of a real ball-screw axis (an excerpt of the EMPS benchmark run) by
   inverse-model least squares.
2. GMS pre-sliding: blocks identified automatically (virgin curve, optimal knots, superposition,
   hysteresis refinement) from a pre-sliding test (small and large sinusoids).
3. Closed-loop quadrant glitches on the paper's axis (``gmsfric.glitch``): tracking error of a
   10 mm, 0.01 Hz sine without friction, with the static map and with GMS.
"""

from __future__ import annotations

import argparse
import time
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import butter, filtfilt

from . import presets
from .io import load_columns
from .models import StaticFriction, Stribeck, simulate_friction
from .cli import Run, declare_files
from .plotting import plot_friction_map, plot_hysteresis
from .results import write_figures


def example_path(name: str) -> Path:
    """Path of an example file shipped in ``gmsfric/data``."""
    return Path(str(resources.files("gmsfric") / "data" / name))


def _inverse_model_static_map(t: np.ndarray, q: np.ndarray, force: np.ndarray) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """EMPS recipe: zero-phase 4th-order Butterworth at 100 Hz, central differences, decimate by
    10, least squares for force = M qdd + Fv qd + Fc sign(qd) + offset."""
    dt = float(np.median(np.diff(t)))
    b, a = butter(4, min(100.0 * 2 * dt, 0.99))
    qf = filtfilt(b, a, q)
    qd = np.gradient(qf, dt)
    qdd = np.gradient(qd, dt)
    keep = slice(49, -49, 10)
    X = np.column_stack([qdd[keep], qd[keep], np.sign(qd[keep]), np.ones_like(qd[keep])])
    theta, *_ = np.linalg.lstsq(X, force[keep], rcond=None)
    err = 100 * np.linalg.norm(force[keep] - X @ theta) / np.linalg.norm(force[keep])
    params = dict(zip(("M", "Fv", "Fc", "offset"), map(float, theta)))
    params["error_pct"] = float(err)
    return params, {"qd": qd[keep], "friction": force[keep] - theta[0] * qdd[keep]}


def run(out: Path, *, plots: bool = True) -> dict[str, Any]:
    out.mkdir(parents=True, exist_ok=True)
    summary: dict[str, Any] = {}

    # 1. static map from the EMPS excerpt
    cols = load_columns(example_path("emps_excerpt.csv"), {"time": "t", "position": "qm", "command": "vir"})
    force = presets.EMPS_GTAU * cols["command"]
    params, pts = _inverse_model_static_map(cols["time"], cols["position"], force)
    summary["static_map"] = params
    print("1. Static friction map of a real ball-screw axis (EMPS excerpt, inverse-model least squares)")
    print(f"   M = {params['M']:.2f} kg, Fv = {params['Fv']:.1f} N s/m, Fc = {params['Fc']:.2f} N, offset = {params['offset']:.2f} N,"
          f" force error {params['error_pct']:.2f} %")
    fitted = StaticFriction(Stribeck(abs(params["Fc"]), abs(params["Fc"]), 1.0), sigma=max(params["Fv"], 0.0), offset=params["offset"])
    if plots:
        fig = plot_friction_map([fitted], ["Coulomb + viscous + offset fit"], v_max=float(np.max(np.abs(pts["qd"]))), data=(pts["qd"], pts["friction"]))
        fig.axes[0].set_title("EMPS excerpt: friction force vs velocity")
        write_figures({"friction_map": fig}, out, dpi=120)

    # 2. GMS pre-sliding: identify the blocks automatically from the virgin-curve test
    from .identify import fit_presliding

    cols = load_columns(example_path("presliding_example.csv"), {"time": "time", "position": "position", "force": "force"})
    truth = presets.paper_gms()
    ident = fit_presliding(cols["time"], cols["position"], cols["force"], stribeck=truth.stribeck, c=truth.c, sigma=truth.sigma, progress=False)
    gms = ident.model_object
    sim = simulate_friction(gms, cols["time"], cols["position"])
    rms = float(np.sqrt(np.mean((sim - cols["force"]) ** 2)))
    summary["presliding"] = {
        "n_blocks": gms.n_blocks,
        "k": [ident.parameters[f"k{i + 1}"][0] for i in range(gms.n_blocks)],
        "w": [ident.parameters[f"w{i + 1}"][0] for i in range(gms.n_blocks)],
        "rms_force_error_N": rms,
    }
    print("2. GMS pre-sliding blocks identified from the example virgin-curve test (made with the paper's Table 2)")
    print(f"   {gms.n_blocks} blocks chosen by BIC; simulated vs measured force rms {rms * 1e3:.3f} mN")
    for i in range(gms.n_blocks):
        (k, sk), (w, sw) = ident.parameters[f"k{i + 1}"], ident.parameters[f"w{i + 1}"]
        print(f"   block {i + 1}: k = {k / 1e3:10.2f} ± {sk / 1e3:.2g} N/mm, w = {w * 1e3:7.3f} ± {sw * 1e3:.2g} mN")
    if plots:
        xv = np.linspace(0, float(np.max(np.abs(cols["position"]))), 400)
        fig = plot_hysteresis(cols["position"], cols["force"], virgin=(xv, gms.virgin_curve(xv)), title="Pre-sliding hysteresis: measured and identified GMS")
        fig.axes[0].plot(cols["position"] * 1e6, sim, "k-", lw=0.6, alpha=0.7, label="identified GMS")
        fig.axes[0].legend(fontsize="small")
        write_figures({"gms_hysteresis": fig}, out, dpi=120)
        write_figures({f"gms_identification_{j + 1}": f for j, f in enumerate(ident.plot().values())}, out, dpi=120)

    # 3. closed-loop glitches: the paper's Fig. 14 scenario (see docs/glitch.md)
    from .glitch import plot_tracking_errors, run_sinusoid

    t0 = time.perf_counter()
    scen = run_sinusoid()
    elapsed = time.perf_counter() - t0
    n_steps = sum(r.t.size for r in scen.runs.values())
    glitch = scen.summary()
    summary["closed_loop"] = {name: {"peak_error_m": float(v["peak_error_m"])} for name, v in glitch.items()}  # type: ignore[arg-type]
    summary["closed_loop"]["steps_per_second"] = n_steps / elapsed
    print("3. Quadrant glitches on the paper's axis (10 mm, 0.01 Hz sine, PID, 1.29 ms delay):"
          f" {len(scen.runs)} runs, {n_steps / 1e6:.0f} M steps in {elapsed:.2f} s")
    labels = {"none": "no friction", "static": "static map (Simulink linear region)", "gms": "GMS", "static_stiction": "static map with true stiction"}
    for name, values in glitch.items():
        print(f"   {labels.get(name, name):>36}: peak glitch {float(values['peak_error_m']) * 1e6:6.3f} µm")  # type: ignore[arg-type]
    if plots:
        write_figures({"closed_loop_glitches": plot_tracking_errors(scen)}, out, dpi=120)
    if plots:
        print(f"Figures saved in {out.resolve()}/")
    return summary


def _cmd(args: argparse.Namespace, run_: Run) -> int:
    run(Path(args.out), plots=not args.no_plots)
    return 0


def register(sub: Any) -> None:
    """Add the ``demo`` command."""
    p = sub.add_parser("demo", help="run the tour on the built-in example data and save figures")
    p.add_argument("--out", default="gmsfric-demo", help="folder for the figures (default: ./gmsfric-demo)")
    p.add_argument("--no-plots", action="store_true", help="print the summary only")
    declare_files(p, output_dirs=("out",))
    p.set_defaults(func=_cmd)
