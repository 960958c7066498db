"""Closed-loop OE: additions on top of the Stribeck-type (velocity-strengthening) friction model."""
import sys
from t5_closed_structures import *

STR = {"M": 95.24, "Fv+": 151.2, "Fv-": 224.1, "Fc+": 21.88, "Fc-": 22.45, "dS": -8.888, "vS": 0.01448, "dSexp": 2.0}
base = ["M", "Fv+", "Fv-", "Fc+", "Fc-", "dS", "vS"]
BOUNDS.update({"Te": (0, 5e-3)})
cases = [
    ("str", {**STR}, base, {}),
    ("str + free exponent", {**STR}, base + ["dSexp"], {}),
    ("str + tau", {**STR, "tau": 0.3e-3}, base + ["tau"], {}),
    ("str + lag Te", {**STR, "Te": 0.3e-3}, base + ["Te"], {}),
    ("str + 1 block", {**STR, "Fc+": STR["Fc+"] - 3, "Fc-": STR["Fc-"] - 3, "bf0": 3.0, "bd0": 3e-5}, base + ["bf0", "bd0"], {"n_blocks": 1}),
    ("str + 2 blocks", {**STR, "Fc+": STR["Fc+"] - 6, "Fc-": STR["Fc-"] - 6, "bf0": 3.0, "bd0": 3e-5, "bf1": 3.0, "bd1": 3e-4}, base + ["bf0", "bd0", "bf1", "bd1"], {"n_blocks": 2}),
    ("str + compliance", {**STR, "mfrac": 0.8, "k": 3e6, "c": 1e3}, base + ["mfrac", "k", "c"], {}),
    ("str + quad viscous", {**STR, "Fv2+": 0.0, "Fv2-": 0.0}, base + ["Fv2+", "Fv2-"], {}),
]
only = sys.argv[1:]
res = []
for name, vals, free, kw in cases:
    if only and name not in only:
        continue
    _, o = run_case(name, vals, free, **kw); res.append(o)
json.dump(res, open("t6_closed_more.json", "w"), indent=1)
