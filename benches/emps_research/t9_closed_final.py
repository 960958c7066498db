"""Closed-loop OE fits started from the inverse-model fit (dir + low-speed term, hold alignment):
the candidate final structures, each term judged on the pulses run."""
import sys
from t5_closed_structures import *

BOUNDS.update({"Te": (0, 5e-3), "dS": (-20, 0)})
IDIM = {"M": 95.02, "Fv+": 156.9, "Fv-": 230.5, "Fc+": 21.23, "Fc-": 21.73, "dS": -6.734, "vS": 0.01539, "dSexp": 2.0, "tau": 0.0}
base = ["M", "Fv+", "Fv-", "Fc+", "Fc-", "dS", "vS"]
cases = [
    ("IDIM params, no refit", IDIM, [], {}),
    ("str (from IDIM)", IDIM, base, {}),
    ("str + tau (from IDIM)", IDIM, base + ["tau"], {}),
    ("str + tau + exponent", IDIM, base + ["tau", "dSexp"], {}),
    ("str + tau + 2 blocks", {**IDIM, "Fc+": IDIM["Fc+"] - 6, "Fc-": IDIM["Fc-"] - 6, "bf0": 4.0, "bd0": 2e-5, "bf1": 2.0, "bd1": 5e-4}, base + ["tau", "bf0", "bd0", "bf1", "bd1"], {"n_blocks": 2}),
    ("str + tau + compliance", {**IDIM, "mfrac": 0.7, "k": 3e6, "c": 2e3}, base + ["tau", "mfrac", "k", "c"], {}),
    ("str + tau + Legendre force deg 4", IDIM, base + ["tau", "cq1", "cq2", "cq3", "cq4"], {"n_cq": 5}),
]
only = sys.argv[1:]
res = []
for name, vals, free, kw in cases:
    if only and name not in only:
        continue
    if not free:
        m = Model(vals, [], **kw)
        c = [rel(r.force, m.simulate(r, closed=True, nsub=10)[1]) for r in (est, val)]
        o = [rmse_open(m.simulate(r, nsub=10)[0], r) * 1e3 for r in (est, val)]
        print(f"{name:34s} closed est {c[0]:.3f}  pulses {c[1]:.3f} % | open {o[0]:.2f}/{o[1]:.2f} mm", flush=True)
        continue
    _, o = run_case(name, vals, free, **kw); res.append(o)
json.dump(res, open("t9_closed_final.json", "w"), indent=1)
