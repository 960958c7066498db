#!/usr/bin/env python
"""Physical sanity checks of the audit's simulator (no tool involved).

    python checks.py [--seed 1] [--out /tmp/audit2_checks]

1. every case of the campaign: tracking error vs travel, finite signals, friction at speed vs Fc,
   sticking in dwells (stick contact: v == 0 exactly), saturation actually reached, redraws
2. clean cases: the baseline fitted on moving rows recovers the rig's M, Fv, Fc
3. step-size convergence: the same run with 4x the substeps
4. planted laws visible in the simulated states: delay (lag of command vs. needed force),
   compliance (load oscillation frequency), pre-sliding (elastic slope after reversals),
   Stribeck (break-away force at the end of dwells above Fc)
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import rigs  # noqa: E402
import run as runmod  # noqa: E402
import truth  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default="/tmp/audit2_checks")
    a = ap.parse_args()
    cases = runmod.build_cases(a.seed)
    out = []
    P = out.append
    stats = dict(max_err=[], rms_err=[], fric=[], dwell_v0=[], dwell_enc=[], attempts=[], sat=[], nonfinite=0)
    par = []
    for c in cases:
        info = runmod.generate(c, a.out)
        stats["attempts"].append(len(info["attempts"]))
        rig = info["rig"]
        for run in ("est", "val"):
            s = info["attempts"][-1][run]
            if "max_err_over_travel" not in s:
                stats["nonfinite"] += 1
                continue
            stats["max_err"].append(s["max_err_over_travel"])
            stats["rms_err"].append(s["rms_err_over_travel"])
            if "friction_moving_over_Fc" in s:
                stats["fric"].append(s["friction_moving_over_Fc"])
            if rig["contact"] == "stick" and "dwell_frac_v0" in s and not c["effects"] and not c["outside"]:
                stats["dwell_v0"].append(s["dwell_frac_v0"])
                stats["dwell_enc"].append(s["dwell_frac_encoder_moving"])
        if rig["ctrl"].get("saturation"):
            sim = rigs.simulate(rig, info["runs"]["est"]["kind"], info["runs"]["est"]["duration"],
                                info["runs"]["est"]["seed"])
            stats["sat"].append(float(np.mean(np.abs(sim["u"]) >= 0.999 * rig["P"]["umax"])))
        if c["category"] == "clean":
            d = os.path.join(a.out, c["id"])
            E = _load(d, info)
            S = truth.prepare(E["t"], E["q"], E["f"], rig["P"]["res"])
            X = truth.design(S, rig, [], "reference")
            m = S["moving"]
            th, *_ = np.linalg.lstsq(X[m], S["f"][m], rcond=None)
            par.append((th[0] / rig["M"] - 1, th[1] / rig["Fv"] - 1, th[2] / rig["Fc"] - 1))
    q = lambda x: np.percentile(x, [50, 90, 100]) if len(x) else [np.nan] * 3  # noqa: E731
    P(f"cases: {len(cases)}; redraws needed: {sum(n > 1 for n in stats['attempts'])} cases "
      f"(max {max(stats['attempts'])} draws); runs with non-finite states: {stats['nonfinite']}")
    P("tracking error / travel, median 90%% max:  max |r - x|: %.4f %.4f %.4f   rms: %.4f %.4f %.4f"
      % (*q(stats["max_err"]), *q(stats["rms_err"])))
    P("friction at speed (|v| > 0.2 vmax) / Fc, median 10%% 90%%: %.2f %.2f %.2f"
      % tuple(np.percentile(stats["fric"], [50, 10, 90])))
    P("stick contact, clean rigs, dwell phases: fraction of time with v == 0 exactly, median/min: %.3f / %.3f;"
      " encoder counts changing in dwell: median/max %.4f / %.4f"
      % (np.median(stats["dwell_v0"]), np.min(stats["dwell_v0"]), np.median(stats["dwell_enc"]),
         np.max(stats["dwell_enc"])))
    P("saturated rigs: fraction of control ticks at the drive limit (est run): " +
      ", ".join(f"{x:.3f}" for x in stats["sat"]))
    par = np.array(par)
    P("clean rigs, baseline on moving rows of est vs. the rig: relative error M, Fv, Fc: median |.| "
      + ", ".join(f"{np.median(np.abs(par[:, i])):.3f}" for i in range(3))
      + "; max |.| " + ", ".join(f"{np.max(np.abs(par[:, i])):.3f}" for i in range(3)))
    # ---- step-size convergence
    conv = []
    for c in cases[::9]:
        with open(os.path.join(a.out, c["id"], "truth.json")) as fh:
            info = json.load(fh)
        rig = info["rig"]
        r = info["runs"]["est"]
        s1 = rigs.simulate(rig, r["kind"], min(r["duration"], 8.0), r["seed"])
        rig2 = json.loads(json.dumps(rig))
        rig2["P"]["nsub"] = rig["P"]["nsub"] * 4
        s2 = rigs.simulate(rig2, r["kind"], min(r["duration"], 8.0), r["seed"])
        dx = float(np.sqrt(np.mean((s1["x"] - s2["x"]) ** 2)))
        conv_u = float(np.sqrt(np.mean((s1["u"] - s2["u"]) ** 2)) / rig["Fc"])
        conv.append((c["id"], dx / rig["res"], dx / rig["L"], conv_u))
    P("step-size convergence (4x substeps): rms position difference in encoder steps and / travel, "
      "rms command difference / Fc:")
    for cid, dxs, dxl, du in conv:
        P(f"    {cid:42s} {dxs:8.2f} steps {dxl:.1e} travel  {du:.4f} Fc")
    # ---- planted laws visible in the states
    P("planted laws seen in the simulated states:")
    for c in cases:
        if c["category"] != "single":
            continue
        e = c["effects"][0]
        with open(os.path.join(a.out, c["id"], "truth.json")) as fh:
            info = json.load(fh)
        rig = info["rig"]
        r = info["runs"]["est"]
        sim = rigs.simulate(rig, r["kind"], r["duration"], r["seed"])
        law = rig["law"][e]
        if e == "input_delay":
            # command vs. the force the axis needed (inertia + friction + ...), lag by cross-correlation
            Tc = sim["Tc"]
            need = rig["M"] * np.gradient(sim["v"], Tc) + sim["ffric"]
            u = sim["u"] - sim["u"].mean()
            nd = need - need.mean()
            lags = np.arange(0, int(0.02 / Tc))
            cc = [np.dot(u[: len(u) - k], nd[k:]) for k in lags]
            P(f"    {c['id']:42s} delay planted {law['tau'] * 1e3:.2f} ms, command leads the needed force by "
              f"{lags[int(np.argmax(cc))] * Tc * 1e3:.2f} ms")
        elif e == "compliance":
            # transfer from motor acceleration to load-motor deflection: peaks at the resonance
            dx = sim["x2"] - sim["x"]
            acc = np.gradient(sim["v"], sim["Tc"])
            w = np.hanning(len(dx))
            f = np.fft.rfftfreq(len(dx), sim["Tc"])
            tf = np.abs(np.fft.rfft(dx * w)) / (np.abs(np.fft.rfft(acc * w)) + 1e-30)
            tf = np.convolve(tf, np.ones(9) / 9, mode="same")
            band = (f > 1.0) & (f < 100.0)
            P(f"    {c['id']:42s} load resonance planted {law['fn']:.2f} Hz (zeta {law['zeta']:.3f}), peak of "
              f"|deflection / motor acceleration| {f[band][np.argmax(tf[band])]:.2f} Hz")
        elif e == "presliding_hysteresis":
            ph = law
            P(f"    {c['id']:42s} elements break at {np.array(ph['D']) / rig['res']} steps, "
              f"carry {ph['share']:.2f} Fc; max total element force seen "
              f"{_element_peak(sim, rig):.2f} Fc")
        elif e == "stribeck":
            bk = _breakaway(sim, rig)
            P(f"    {c['id']:42s} Fs/Fc planted {(rig['Fc'] + law['dFs']) / rig['Fc']:.2f} (vs {law['vs']:.3g}); "
              f"peak friction at break-away / Fc: {bk}")
    txt = "\n".join(out)
    print(txt)
    with open(os.path.join(a.out, "checks.txt"), "w") as fh:
        fh.write(txt + "\n")


def _load(d, info):
    import numpy as np
    u = info["units"]
    x = np.genfromtxt(os.path.join(d, "est.csv"), delimiter=",", names=True)
    n = x.dtype.names
    t = x[n[0]] / runmod.TSCALE[u["time"]]
    q = x[n[1]] / runmod.PSCALE[u["position"]]
    f = x[n[2]] * u["gain"] if u["command"] else x[n[2]] / runmod.FSCALE[u["force"]]
    return dict(t=t, q=q, f=f)


def _element_peak(sim, rig):
    el = rig["elements"]
    k, D = np.array(el["k"]), np.array(el["D"])
    F = truth.maxwell_slip(sim["x"], k, D)
    return float(np.max(np.abs(F)) / rig["Fc"])


def _breakaway(sim, rig):
    """largest friction magnitude in the 50 ms after the axis leaves a standstill, over Fc"""
    v = sim["v"]
    moving = v != 0.0 if rig["contact"] == "stick" else np.abs(v) > 1e-3 * rig["vmax"]
    starts = np.where(moving[1:] & ~moving[:-1])[0]
    n = int(0.05 / sim["Tc"])
    peaks = [np.max(np.abs(sim["ffric"][s:s + n])) for s in starts if s + n < len(v) and s > n]
    return f"{np.median(peaks) / rig['Fc']:.2f} (median of {len(peaks)})" if peaks else "no start"


if __name__ == "__main__":
    main()
