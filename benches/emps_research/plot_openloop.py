"""Open-loop error of a model over time on both runs (diagnostic figure)."""
import sys
import numpy as np
from matplotlib.figure import Figure
from emps import *

def figure(p, fname, **kw):
    est, val = runs()
    fig = Figure(figsize=(14, 8)); axs = fig.subplots(3, 2)
    for j, r in enumerate((est, val)):
        q, f, v = sim(p, r, **kw)
        vm = np.gradient(r.qm, DT)
        axs[0, j].plot(r.t, (q - r.qm) * 1e3); axs[0, j].set_ylabel('q_sim - qm (mm)')
        axs[0, j].set_title(f"{r.name}: rmse {rmse_open(q, r)*1e3:.3f} mm")
        axs[1, j].plot(r.t, (v - vm) * 1e3, lw=0.5); axs[1, j].set_ylabel('v_sim - v (mm/s)'); axs[1, j].set_ylim(-20, 20)
        axs[2, j].plot(r.t, vm, lw=0.5); axs[2, j].plot(r.t, v, lw=0.5); axs[2, j].set_ylabel('v (m/s)')
        for a in axs[:, j]: a.set_xlabel('t (s)')
    fig.tight_layout(); fig.savefig(fname, dpi=70)

if __name__ == '__main__':
    figure(base_params(95.11, 203.5, 20.39, -3.16), 'openloop_reference.png', nsub=5)
