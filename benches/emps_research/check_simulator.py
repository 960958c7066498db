"""Checks of the numba simulator: (1) linear axis (no Coulomb) against the exact ZOH
discretisation (scipy cont2discrete), open loop and closed loop; (2) substep convergence of the
final model; (3) a delay of exactly one sample equals shifting the input by one sample."""
import numpy as np
from scipy import signal
from emps import *

est, val = runs()
# (1) linear: M qdd = F - Fv v
M, Fv = 95.0, 200.0
A = np.array([[0, 1], [0, -Fv / M]]); B = np.array([[0], [1 / M]]); C = np.eye(2); Dm = np.zeros((2, 1))
Ad, Bd, *_ = signal.cont2discrete((A, B, C, Dm), DT, method="zoh")
x = np.array([est.qm[0], initial_velocity(est)])
q_exact = np.empty(est.t.size)
for k in range(est.t.size):
    q_exact[k] = x[0]
    x = Ad @ x + Bd[:, 0] * est.force[k]
m = Model({"M": M, "Fv": Fv, "Fc": 0.0}, [])
for nsub in (1, 4, 10):
    q = m.simulate(est, nsub=nsub)[0]
    print(f"linear open loop, nsub {nsub:2d}: max |q - q_exact| = {np.max(np.abs(q - q_exact))*1e6:.3f} um (travel 250 mm)")
# closed loop linear: exact ZOH loop
x = np.array([est.qm[0], initial_velocity(est)]); v0 = x[1]
qp = x[0] - v0 * DT; qfp = qp - 0.5 * v0 * DT
f_exact = np.empty(est.t.size)
for k in range(est.t.size):
    q = x[0]; qf = 0.5 * q + 0.5 * qp; qd = (qf - qfp) / DT
    u = np.clip(est.kp * est.kv * (est.qg[k] - q) - est.kv * qd, -10, 10) * est.gtau
    f_exact[k] = u; qp, qfp = q, qf
    x = Ad @ x + Bd[:, 0] * u
f = m.simulate(est, closed=True, nsub=4)[1]
print(f"linear closed loop, nsub 4: max |f - f_exact| = {np.max(np.abs(f - f_exact)):.2e} N")
# (2) convergence of the final closed-loop model
FINAL = {"M": 95.103, "Fv+": 157.15, "Fv-": 230.0, "Fc+": 21.271, "Fc-": 21.843, "dS": -9.5805, "vS": 0.012761, "dSexp": 2.0, "tau": 0.30293e-3}
mf = Model(FINAL, [])
for nsub in (2, 4, 10, 20, 50):
    c = [rel(r.force, mf.simulate(r, closed=True, nsub=nsub)[1]) for r in (est, val)]
    o = [rmse_open(mf.simulate(r, nsub=nsub)[0], r) * 1e3 for r in (est, val)]
    print(f"final model nsub {nsub:2d}: closed {c[0]:.4f} / {c[1]:.4f} %   open {o[0]:.4f} / {o[1]:.4f} mm")
# (3) one-sample delay
m1 = Model({**FINAL, "tau": DT}, [])
r_shift = Run(est.name, est.t, est.qm, est.qg, np.r_[est.vir[0], est.vir[:-1]], est.pulses, est.gtau, est.kp, est.kv)
d = np.max(np.abs(m1.simulate(est, nsub=10)[0] - Model({**FINAL, "tau": 0.0}, []).simulate(r_shift, nsub=10)[0]))
print(f"delay of one sample vs input shifted by one sample: max diff {d*1e9:.3f} nm")
