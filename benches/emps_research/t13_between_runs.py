"""Diagnostic only (never used for a score): the final closed-loop structure fitted on each run
separately, to show what changes between the runs."""
from t5_closed_structures import BOUNDS, est, val
from emps import *

BOUNDS.update({"dS": (-20, 0), "tau": (0, 3e-3)})
start = {"M": 95.1, "Fv+": 157.2, "Fv-": 230.0, "Fc+": 21.27, "Fc-": 21.84, "dS": -9.58, "vS": 0.01276, "tau": 0.30e-3, "dSexp": 2.0}
free = ["M", "Fv+", "Fv-", "Fc+", "Fc-", "dS", "vS", "tau"]
fits = {}
for r in (est, val):
    m, _ = fit_oe(Model(start, free), r, closed=True, nsub=4, bounds=BOUNDS, max_nfev=300)
    fits[r.name] = m
    print(f"fitted on {r.name:22s}: in-run closed-loop force error {rel(r.force, m.simulate(r, closed=True, nsub=10)[1]):.3f} %")
print(f"{'param':6s} {'estimation':>12s} {'pulses':>12s} {'change':>8s}")
for k in free:
    a, b = fits[est.name].values[k], fits[val.name].values[k]
    print(f"{k:6s} {a:12.5g} {b:12.5g} {100 * (b - a) / abs(a):+7.2f}%")
for v in (0.042, 0.083, 0.125):
    for s in (1, -1):
        F = []
        for m in fits.values():
            p, *_ = m.unpack()
            fc = p[P_FCP] if s > 0 else p[P_FCN]; fv = p[P_FVP] if s > 0 else p[P_FVN]
            F.append(fc + p[P_DS] * np.exp(-(v / p[P_VS]) ** 2) + fv * v)
        print(f"  friction at {s * v:+.3f} m/s: est {F[0]:.2f} N, pulses {F[1]:.2f} N, diff {F[1] - F[0]:+.2f} N")
