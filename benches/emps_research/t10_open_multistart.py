"""Open-loop OE on the estimation run from several starts: how much the held-out (pulses) RMSE
depends on which local minimum the fit lands in, for the reference and per-direction structures."""
import numpy as np
from emps import *

est, val = runs()
rng = np.random.default_rng(1)
for name, start, free in (("ref", {"M": 95.06, "Fv": 203.4, "Fc": 20.41, "off": -3.17}, ["M", "Fv", "Fc", "off"]),
                          ("dir", {"M": 95.1, "Fv+": 166.7, "Fv-": 240.3, "Fc+": 20.14, "Fc-": 20.64}, ["M", "Fv+", "Fv-", "Fc+", "Fc-"]),
                          ("dir+lowspeed+tau", {"M": 95.1, "Fv+": 157.2, "Fv-": 230.0, "Fc+": 21.27, "Fc-": 21.84, "dS": -9.58, "vS": 0.01276, "tau": 0.3e-3},
                           ["M", "Fv+", "Fv-", "Fc+", "Fc-", "dS", "vS", "tau"])):
    rows = []
    for i in range(6):
        s = {k: v * (1 + 0.03 * rng.standard_normal()) if i else v for k, v in start.items()}
        m, res = fit_oe(Model(s, free), est, nsub=4, max_nfev=300,
                        bounds={"vS": (1e-3, 0.1), "dS": (-20, 0), "tau": (0, 2e-3)})
        o = [rmse_open(m.simulate(r, nsub=10)[0], r) * 1e3 for r in (est, val)]
        rows.append(o)
        print(f"{name:18s} start {i}: est {o[0]:.3f} mm  pulses {o[1]:.3f} mm  nfev {m.nfev}  ", {k: round(v, 3) for k, v in m.values.items() if k in free}, flush=True)
