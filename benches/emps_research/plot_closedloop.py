"""Closed-loop force error of a model over time on both runs (diagnostic figure)."""
import numpy as np
from matplotlib.figure import Figure
from emps import *


def figure(m: Model, fname, nsub=10, zoom=(2.0, 4.0)):
    est, val = runs()
    fig = Figure(figsize=(14, 9)); axs = fig.subplots(3, 2)
    for j, r in enumerate((est, val)):
        q, f, v = m.simulate(r, closed=True, nsub=nsub)
        e = f - r.force
        axs[0, j].plot(r.t, e, lw=0.4); axs[0, j].set_ylabel('f_sim - f (N)')
        axs[0, j].set_title(f"{r.name}: force error {rel(r.force, f):.2f} %")
        sl = (r.t >= zoom[0]) & (r.t < zoom[1])
        axs[1, j].plot(r.t[sl], r.force[sl], lw=0.6, label='measured'); axs[1, j].plot(r.t[sl], f[sl], lw=0.6, label='sim')
        axs[1, j].set_ylabel('force (N)'); axs[1, j].legend(fontsize=7)
        # error binned by velocity
        vm = np.gradient(r.qm, DT)
        bins = np.linspace(-0.14, 0.14, 57)
        idx = np.digitize(vm, bins)
        mu = [e[idx == i].mean() if np.sum(idx == i) > 20 else np.nan for i in range(1, bins.size)]
        sd = [e[idx == i].std() if np.sum(idx == i) > 20 else np.nan for i in range(1, bins.size)]
        axs[2, j].plot(0.5 * (bins[1:] + bins[:-1]), mu, 'o-', ms=3, label='mean')
        axs[2, j].plot(0.5 * (bins[1:] + bins[:-1]), sd, 's-', ms=3, label='std')
        axs[2, j].set_xlabel('v (m/s)'); axs[2, j].set_ylabel('force error (N)'); axs[2, j].legend(fontsize=7)
        axs[0, j].set_xlabel('t (s)'); axs[1, j].set_xlabel('t (s)')
    fig.tight_layout(); fig.savefig(fname, dpi=70)


if __name__ == '__main__':
    m = Model({'M': 93.66, 'Fv+': 166.7, 'Fv-': 242.9, 'Fc+': 20.43, 'Fc-': 20.78}, [])
    figure(m, 'closedloop_dir.png')
