"""Can the protocol's 20-sample initialisation window reveal the run's friction level?

With the closed-loop-fitted model, estimate (v0, a common Coulomb shift dFc) from the first 20
samples of each run (least squares on position); if the window carried the between-run friction
change, dFc would come out ~+1 N on the pulses run and ~0 on the estimation run."""
import numpy as np
from scipy.optimize import least_squares
from emps import *

est, val = runs()
BEST = {"M": 95.1, "Fv+": 157.2, "Fv-": 230.0, "Fc+": 21.27, "Fc-": 21.84, "dS": -9.58, "vS": 0.01276, "tau": 0.30e-3}
for r in (est, val):
    n = 20
    short = Run(r.name, r.t[:n], r.qm[:n], r.qg[:n], r.vir[:n], r.pulses[:n], r.gtau, r.kp, r.kv)
    def res(z):
        v = dict(BEST); v["Fc+"] += z[1]; v["Fc-"] += z[1]
        q, _, _ = Model(v, []).simulate(short, nsub=10, v0=z[0])
        return (q - short.qm) * 1e6
    s = least_squares(res, [initial_velocity(r), 0.0], x_scale=[1e-3, 1.0])
    J = s.jac; cov = np.linalg.pinv(J.T @ J) * (2 * s.cost / (n - 2))
    print(f"{r.name}: v0 = {s.x[0]*1e3:.3f} mm/s, dFc = {s.x[1]:+.2f} ± {np.sqrt(cov[1,1]):.2f} N, rms fit {np.sqrt(2*s.cost/n):.3f} um")
