"""What limits the final closed-loop model: error budget on both runs, and the position ripple
(2.5 mm / 5.43 mm periods) that is position-locked within a run but not between runs."""
import numpy as np
from scipy import signal
from gmsfric.loop.select import _chunk_t
from t5_closed_structures import BOUNDS, est, val
from friction_excess import plateau_mask
from emps import *

FINAL = {"M": 95.103, "Fv+": 157.15, "Fv-": 230.0, "Fc+": 21.271, "Fc-": 21.843, "dS": -9.5805, "vS": 0.012761, "dSexp": 2.0, "tau": 0.30293e-3}
mf = Model(FINAL, [])
for r in (est, val):
    f = mf.simulate(r, closed=True, nsub=10)[1]
    e = f - r.force; tot = e @ e
    near = np.zeros(r.t.size, bool)
    for k in np.flatnonzero(np.diff(r.pulses) != 0):
        near[k - 5:k + 60] = True
    ok, lev, v = plateau_mask(r)
    b, a = signal.butter(4, 5 / 500); slow = signal.filtfilt(b, a, e)
    print(f"{r.name}: error {rel(r.force, f):.3f} %; share of squared error: near pulse edges {np.sum(e[near]**2)/tot:.2f} "
          f"({near.mean():.2f} of samples), plateaus {np.sum(e[ok]**2)/tot:.2f} ({ok.mean():.2f}), below 5 Hz {slow @ slow / tot:.2f}")
    for i, L in enumerate((-0.125, -0.083, -0.042, 0.042, 0.083, 0.125)):
        m = ok & (lev == i)
        print(f"     plateau {L:+.3f} m/s: mean force error {e[m].mean():+.2f} N, std {e[m].std():.2f} N")

# ripple in the closed loop: Fourier force terms at 2.5 and 5.43 mm, fitted on the estimation run
per = (2.5e-3, 5.43e-3)
free = ["fqa0", "fqb0", "fqa1", "fqb1"]
m, _ = fit_oe(Model({**FINAL, **{k: 0.0 for k in free}}, free, periods=per), est, closed=True, nsub=4, max_nfev=100)
fe0 = mf.simulate(est, closed=True, nsub=10)[1]; fv0 = mf.simulate(val, closed=True, nsub=10)[1]
fe1 = m.simulate(est, closed=True, nsub=10)[1]; fv1 = m.simulate(val, closed=True, nsub=10)[1]
print("ripple terms fitted on est:", {k: round(m.values[k], 3) for k in free})
print(f"  + ripple: est {rel(est.force, fe0):.3f} -> {rel(est.force, fe1):.3f} %,  pulses {rel(val.force, fv0):.3f} -> {rel(val.force, fv1):.3f} %, t(pulses) = {_chunk_t(fv0 - val.force, fv1 - val.force, 250):.2f}")
# same ripple with the position origin shifted (diagnostic: the phase offset between runs)
for dq in (1.0e-3, 1.77e-3, 2.0e-3):
    r2 = Run(val.name, val.t, val.qm + dq, val.qg + dq, val.vir, val.pulses, val.gtau, val.kp, val.kv)
    fv2 = m.simulate(r2, closed=True, nsub=10)[1]
    print(f"  (diagnostic) ripple with the pulses run's origin shifted {dq*1e3:.2f} mm: pulses {rel(val.force, fv2):.3f} %")
