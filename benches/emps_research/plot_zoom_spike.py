"""Zoom on the largest closed-loop force error of the final model (the top reversal)."""
import json, numpy as np
from matplotlib.figure import Figure
from emps import *
est, val = runs()
m = Model(json.load(open("t16_final.json"))["IDIM final (loop), simulated as is"]["params"], [])
q, f, v = m.simulate(est, closed=True, nsub=10)
e = f - est.force
i = np.argsort(e)[:8]; print("largest negative errors at t =", np.round(est.t[np.sort(i)], 3), "q =", np.round(est.qm[np.sort(i)]*1e3, 2))
fig = Figure(figsize=(12, 7)); ax = fig.subplots(3, 1, sharex=True)
k = int(np.argmin(e)); sl = slice(k - 150, k + 150)
ax[0].plot(est.t[sl], est.force[sl], label="measured"); ax[0].plot(est.t[sl], f[sl], label="sim"); ax[0].set_ylabel("force (N)"); ax[0].legend()
ax[1].plot(est.t[sl], np.gradient(est.qm, DT)[sl], label="measured"); ax[1].plot(est.t[sl], v[sl], label="sim"); ax[1].set_ylabel("v (m/s)")
ax[2].plot(est.t[sl], (est.qg[sl]) * 1e3); ax[2].set_ylabel("qg (mm)"); ax[2].set_xlabel("t (s)")
fig.tight_layout(); fig.savefig("zoom_spike.png", dpi=70)
