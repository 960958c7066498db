"""Open-loop output-error fits of candidate structures on the estimation run, scored on the pulses run.

Each structure starts from the per-direction OE fit (itself started from the IDIM fit); position
bases are defined on the estimation travel [0, 0.25] m.  Printed: estimation RMSE (in-sample),
pulses RMSE (held-out), closed-loop force errors of the same model, parameters, simulations used.
"""
import json, sys, time
import numpy as np
from emps import *

est, val = runs()
BOUNDS = {"vS": (1e-4, 0.2), "dS": (-20, 20), "tau": (0, 3e-3), "dSexp": (0.3, 4), "wE0": (1, 1e6),
          "tth": (0.5, 1e3), "mfrac": (0.05, 0.95), "k": (1e3, 1e9), "c": (0, 1e5)}

DIR = {"M": 95.1, "Fv+": 166.7, "Fv-": 240.3, "Fc+": 20.14, "Fc-": 20.64}


def run_case(name, values, free, nsub=4, **kw):
    t0 = time.time()
    m0 = Model(values, free, **kw)
    m, res = fit_oe(m0, est, nsub=nsub, bounds=BOUNDS, max_nfev=400)
    o = [rmse_open(m.simulate(r, nsub=10)[0], r) * 1e3 for r in (est, val)]
    c = [rel(r.force, m.simulate(r, closed=True, nsub=10)[1]) for r in (est, val)]
    out = {"name": name, "open_mm": o, "closed_pct": c, "nfev": m.nfev, "s": time.time() - t0,
           "params": {k: (m.values[k], m.std[k]) for k in free}}
    print(f"{name:34s} open est {o[0]:6.3f}  pulses {o[1]:6.3f} mm | closed {c[0]:.2f}/{c[1]:.2f} % | nfev {m.nfev:4d} {out['s']:.0f}s", flush=True)
    print("      ", {k: f"{v:.4g}±{s:.2g}" for k, (v, s) in out["params"].items()}, flush=True)
    return m, out


if __name__ == "__main__":
    results = []
    m_ref, o = run_case("ref: M Fv Fc off", {"M": 95.06, "Fv": 203.4, "Fc": 20.41, "off": -3.17}, ["M", "Fv", "Fc", "off"]); results.append(o)
    m_dir, o = run_case("dir: M Fv± Fc±", DIR, list(DIR)); results.append(o)
    d = dict(m_dir.values)
    base = list(DIR)
    cases = [
        ("dir + tau", {**d, "tau": 0.5e-3}, base + ["tau"], {}),
        ("dir + stribeck (dS, vS)", {**d, "dS": 2.0, "vS": 0.01, "dSexp": 2.0}, base + ["dS", "vS"], {}),
        ("dir + quadratic viscous", {**d, "Fv2+": 0.0, "Fv2-": 0.0}, base + ["Fv2+", "Fv2-"], {}),
        ("dir + pos force Leg1..3", {**d}, base + ["cq1", "cq2", "cq3"], {"n_cq": 4}),
        ("dir + pos friction Leg0..3", {**d}, base + ["cf1", "cf2", "cf3"], {"n_cf": 4}),
        ("dir + warm-up (Fc,Fv relax w/ energy)", {**d, "wac": 0.02, "wav": 0.02, "wE0": 100.0}, base + ["wac", "wav", "wE0"], {}),
        ("dir + thermal state (tbc,tbv,tth)", {**d, "tbc": 1e-4, "tbv": 1e-4, "tth": 10.0}, base + ["tbc", "tbv", "tth"], {}),
        ("dir + compliance", {**d, "mfrac": 0.5, "k": 1e6, "c": 1e3}, base + ["mfrac", "k", "c"], {}),
    ]
    only = sys.argv[1:] 
    for name, vals, free, kw in cases:
        if only and not any(s in name for s in only):
            continue
        _, o = run_case(name, vals, free, **kw)
        results.append(o)
    json.dump(results, open("t4_open_structures.json", "w"), indent=1)
