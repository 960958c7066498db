"""Closed-loop output-error fits (force error, the controller simulated) on the estimation run;
scored on the pulses run (pulses added to the controller output)."""
import json, sys, time
import numpy as np
from emps import *

est, val = runs()
BOUNDS = {"vS": (1e-4, 0.2), "dS": (-20, 20), "tau": (0, 3e-3), "dSexp": (0.3, 4),
          "mfrac": (0.05, 0.95), "k": (1e3, 1e9), "c": (0, 1e5),
          **{f"bf{i}": (0, 40) for i in range(4)}, **{f"bd{i}": (1e-7, 5e-3) for i in range(4)},
          "Fc+": (0, 40), "Fc-": (0, 40)}
DIR = {"M": 93.66, "Fv+": 166.7, "Fv-": 242.9, "Fc+": 20.43, "Fc-": 20.78}


def run_case(name, values, free, nsub=4, max_nfev=300, **kw):
    t0 = time.time()
    m0 = Model(values, free, **kw)
    m, res = fit_oe(m0, est, closed=True, nsub=nsub, bounds=BOUNDS, max_nfev=max_nfev)
    c = [rel(r.force, m.simulate(r, closed=True, nsub=10)[1]) for r in (est, val)]
    o = [rmse_open(m.simulate(r, nsub=10)[0], r) * 1e3 for r in (est, val)]
    out = {"name": name, "closed_pct": c, "open_mm": o, "nfev": m.nfev, "s": time.time() - t0,
           "params": {k: (m.values[k], m.std[k]) for k in free}}
    print(f"{name:34s} closed est {c[0]:.3f}  pulses {c[1]:.3f} % | open {o[0]:.2f}/{o[1]:.2f} mm | nfev {m.nfev:4d} {out['s']:.0f}s", flush=True)
    print("      ", {k: f"{v:.4g}±{s:.2g}" for k, (v, s) in out["params"].items()}, flush=True)
    return m, out


if __name__ == "__main__":
    results = []
    m_dir, o = run_case("dir", DIR, list(DIR)); results.append(o)
    d = dict(m_dir.values); base = list(DIR)
    cases = [
        ("dir + tau", {**d, "tau": 0.3e-3}, base + ["tau"], {}),
        ("dir + stribeck", {**d, "dS": -2.0, "vS": 0.005, "dSexp": 1.0}, base + ["dS", "vS"], {}),
        ("dir + 2 blocks", {**d, "Fc+": d["Fc+"] - 8, "Fc-": d["Fc-"] - 8, "bf0": 4.0, "bd0": 1e-5, "bf1": 4.0, "bd1": 1e-4},
         base + ["bf0", "bd0", "bf1", "bd1"], {"n_blocks": 2}),
        ("dir + 2 blocks + tau", {**d, "Fc+": d["Fc+"] - 8, "Fc-": d["Fc-"] - 8, "bf0": 4.0, "bd0": 1e-5, "bf1": 4.0, "bd1": 1e-4, "tau": 0.3e-3},
         base + ["bf0", "bd0", "bf1", "bd1", "tau"], {"n_blocks": 2}),
    ]
    only = sys.argv[1:]
    for name, vals, free, kw in cases:
        if only and not any(s == name for s in only):
            continue
        _, o = run_case(name, vals, free, **kw); results.append(o)
    json.dump(results, open("t5_closed_structures.json", "w"), indent=1)
