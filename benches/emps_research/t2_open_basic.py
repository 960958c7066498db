"""Open-loop OE fits of basic structures on the estimation run; scored on the pulses run."""
import time
import numpy as np
from emps import *

est, val = runs()
start = {"M": 95.1, "Fv+": 166.7, "Fv-": 240.3, "Fc+": 20.14, "Fc-": 20.64, "off": 0.0}
cases = {
    "ref (M,Fv,Fc,off)": ["M", "Fv", "Fc", "off"],
    "dir (M,Fv±,Fc±)": ["M", "Fv+", "Fv-", "Fc+", "Fc-"],
    "dir, no M": ["Fv+", "Fv-", "Fc+", "Fc-"],
}
for name, free in cases.items():
    vals = dict(start)
    if "Fv" in free:
        vals = {"M": 95.06, "Fv": 203.4, "Fc": 20.41}
        vals["off"] = -3.16
    m0 = Model(vals, free)
    s0 = m0.scores(est, val)
    t0 = time.time()
    m, res = fit_oe(m0, est)
    s = m.scores(est, val)
    print(f"{name:22s} start open {s0['open_mm'][0]:.3f}/{s0['open_mm'][1]:.3f} mm -> fitted {s['open_mm'][0]:.3f}/{s['open_mm'][1]:.3f} mm,"
          f" closed {s['closed_force_pct'][0]:.2f}/{s['closed_force_pct'][1]:.2f} %  nfev {m.nfev} {time.time()-t0:.1f}s")
    print("    ", {k: f"{m.values[k]:.4g}±{m.std[k]:.2g}" for k in free})
    # oracle (diagnostic only, fit on pulses run)
    mo, _ = fit_oe(m0, val)
    so = mo.scores(est, val)
    print(f"    oracle (fit on pulses, diagnostic only): open {so['open_mm'][0]:.3f}/{so['open_mm'][1]:.3f}", {k: round(mo.values[k], 3) for k in free})
