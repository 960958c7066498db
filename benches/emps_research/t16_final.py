"""Final models.  The inverse-model (IDIM) result of the package's loop with the low-speed term
allowed (t15), simulated as is in closed and open loop, then refined by closed-loop output error
on the estimation run (started from it), and scored on the pulses run."""
import json
import numpy as np
from gmsfric.loop.select import _chunk_t
from t5_closed_structures import BOUNDS, est, val
from emps import *

BOUNDS.update({"dS": (-20, 0), "tau": (0, 3e-3), "dSexp": (0.3, 4)})
L = json.load(open("t15_loop_with_lowspeed.json"))
p = {k: v["value"] for k, v in L["final"]["parameters"].items()} if "final" in L and "parameters" in L["final"] else None
if p is None:
    raise SystemExit(f"unexpected JSON layout: {list(L)}")
Fv, dFv, Fc, off, dFm = p["Fv"], p["dFv_asym"], p["Fc"], p["offset"], p["dF_moving"]
IDIM = {"M": p["M"], "Fv+": Fv + dFv, "Fv-": Fv - dFv, "Fc+": Fc + off + dFm, "Fc-": Fc - off - dFm,
        "dS": p["Fs_minus_Fc"], "vS": p["vs"], "dSexp": p["stribeck_delta"], "tau": p["delay_s"] - p["sampling_hold_s"]}
# at rest the IDIM model has the offset alone; the simulator's rest force is set-valued (stiction)
print("IDIM final mapped to the simulator:", {k: round(v, 5) for k, v in IDIM.items()})
out = {}


def report(name, m):
    fe = m.simulate(est, closed=True, nsub=10)[1]; fv = m.simulate(val, closed=True, nsub=10)[1]
    o = [rmse_open(m.simulate(r, nsub=10)[0], r) * 1e3 for r in (est, val)]
    print(f"{name:46s} closed est {rel(est.force, fe):.3f} %  pulses {rel(val.force, fv):.3f} % | open est {o[0]:.3f} mm  pulses {o[1]:.3f} mm")
    out[name] = {"closed_pct": [rel(est.force, fe), rel(val.force, fv)], "open_mm": o, "params": m.values,
                 "std": getattr(m, "std", {}), "nfev": getattr(m, "nfev", 0)}
    return fe, fv


report("IDIM final (loop), simulated as is", Model(IDIM, []))
free = ["M", "Fv+", "Fv-", "Fc+", "Fc-", "dS", "vS", "tau"]
m1, _ = fit_oe(Model(IDIM, free), est, closed=True, nsub=4, bounds=BOUNDS, max_nfev=400)
report("closed-loop OE from IDIM (exp 1)", m1)
print("      ", {k: f"{m1.values[k]:.5g}±{m1.std[k]:.2g}" for k in free}, "simulations:", m1.nfev)
m2, _ = fit_oe(Model(IDIM, free + ["dSexp"]), est, closed=True, nsub=4, bounds=BOUNDS, max_nfev=400)
report("closed-loop OE from IDIM (exponent free)", m2)
print("      ", {k: f"{m2.values[k]:.5g}±{m2.std[k]:.2g}" for k in free + ["dSexp"]}, "simulations:", m2.nfev)
json.dump(out, open("t16_final.json", "w"), indent=1)
