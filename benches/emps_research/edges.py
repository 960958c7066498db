"""Average force response around the pulse edges (pulses run): measured vs simulated closed loop."""
import numpy as np
from matplotlib.figure import Figure
from emps import *


def edge_average(m: Model, pre=10, post=120, nsub=10):
    est, val = runs()
    q, f, v = m.simulate(val, closed=True, nsub=nsub)
    edges = np.flatnonzero(np.diff(val.pulses) != 0) + 1
    out = {}
    for kind, sel in (("rising", np.diff(val.pulses)[edges - 1] > 0), ("falling", np.diff(val.pulses)[edges - 1] < 0)):
        E = edges[sel]
        E = E[(E > pre) & (E < val.t.size - post)]
        idx = E[:, None] + np.arange(-pre, post)[None, :]
        base_m = val.force[E - 2][:, None]
        out[kind] = (np.arange(-pre, post) * DT, (val.force[idx] - base_m).mean(0), (f[idx] - base_m).mean(0),
                     (val.qm[idx] - q[idx]).mean(0))
    return out


if __name__ == "__main__":
    import sys
    m = Model({'M': 95.24, 'Fv+': 151.2, 'Fv-': 224.1, 'Fc+': 21.88, 'Fc-': 22.45, 'dS': -8.888, 'vS': 0.01448, 'dSexp': 2.0}, [])
    out = edge_average(m)
    fig = Figure(figsize=(12, 7)); axs = fig.subplots(2, 2)
    for j, (kind, (t, fm, fs, dq)) in enumerate(out.items()):
        axs[0, j].plot(t * 1e3, fm, label="measured"); axs[0, j].plot(t * 1e3, fs, label="sim")
        axs[0, j].plot(t * 1e3, fs - fm, label="sim - meas"); axs[0, j].legend(); axs[0, j].set_title(kind)
        axs[0, j].set_xlabel("time from edge (ms)"); axs[0, j].set_ylabel("force - force before edge (N)")
        axs[1, j].plot(t * 1e3, dq * 1e6); axs[1, j].set_xlabel("time from edge (ms)"); axs[1, j].set_ylabel("qm - q_sim (um)")
    fig.tight_layout(); fig.savefig("edges_stribeck.png", dpi=70)
