"""Diagnostic (not a model): how much of the pulses-run open-loop error is a between-run friction shift?

Take the estimation-run OE fit of the per-direction model and refit on the PULSES run only one
common friction change (a Coulomb shift dFc on both directions, or a viscous scale). If one
number brings the pulses RMSE near the in-run level, the between-run change is the limit.
"""
import numpy as np
from emps import *

est, val = runs()
base = {"M": 95.1, "Fv+": 166.7, "Fv-": 240.3, "Fc+": 20.14, "Fc-": 20.64}
m_est, _ = fit_oe(Model(base, list(base)), est)
print("est fit", {k: round(v, 3) for k, v in m_est.values.items()}, m_est.scores(est, val)["open_mm"])
from scipy.optimize import least_squares
for kind in ("coulomb", "viscous_scale", "both"):
    def make(z):
        v = dict(m_est.values)
        if kind in ("coulomb", "both"):
            v["Fc+"] += z[0]; v["Fc-"] += z[0]
        if kind in ("viscous_scale", "both"):
            v["Fv+"] *= 1 + z[-1]; v["Fv-"] *= 1 + z[-1]
        return Model(v, [])
    n = 2 if kind == "both" else 1
    r = least_squares(lambda z: (make(z).simulate(val)[0] - val.qm)[N_SKIP:], np.zeros(n), diff_step=1e-3)
    print(f"{kind:14s} shift on pulses run: {np.round(r.x, 4)} -> pulses RMSE {rmse_open(make(r.x).simulate(val)[0], val)*1e3:.3f} mm")

# drive-gain hypothesis: force = lam * gtau * vir on the pulses run (motor constant change)
def make_gain(z):
    class R: pass
    r = Run(val.name, val.t, val.qm, val.qg, val.vir * (1 + z[0]), val.pulses, val.gtau, val.kp, val.kv)
    return r
r = least_squares(lambda z: (m_est.simulate(make_gain(z))[0] - val.qm)[N_SKIP:], np.zeros(1), diff_step=1e-3)
print(f"gain change on pulses run: {r.x} -> pulses RMSE {rmse_open(m_est.simulate(make_gain(r.x))[0], val)*1e3:.3f} mm")
for rr in (est, val):
    print(rr.name, "mean vir^2", np.mean(rr.vir**2), "mean |vir|", np.mean(np.abs(rr.vir)), "mean force^2", np.mean(rr.force**2))
