"""Friction excess of a run relative to the estimation run's plateau map, over time.

On plateau samples (|a| small, away from pulse edges) the force minus the estimation run's mean
plateau force at the same velocity level; binned in time and by time since the last pulse edge.
"""
import numpy as np
from scipy import signal
from matplotlib.figure import Figure
from emps import *

LEVELS = np.array([-0.1247, -0.0826, -0.0421, 0.0421, 0.0826, 0.1247])


def plateau_mask(r, guard=0.15):
    b, a = signal.butter(4, 20 / 500)
    qf = signal.filtfilt(b, a, r.qm)
    v = np.gradient(qf, DT); acc = np.gradient(v, DT)
    ok = np.abs(acc) < 0.02
    for e in np.flatnonzero(np.diff(r.pulses) != 0):
        ok[e: e + int(guard / DT)] = False
    lev = np.argmin(np.abs(v[:, None] - LEVELS[None, :]), axis=1)
    ok &= np.abs(v - LEVELS[lev]) < 0.01
    return ok, lev, v


def excess(r, ref):
    okr, levr, _ = plateau_mask(ref)
    mref = np.array([ref.force[okr & (levr == i)].mean() for i in range(6)])
    ok, lev, v = plateau_mask(r)
    return ok, lev, r.force - mref[lev]


if __name__ == '__main__':
    est, val = runs()
    fig = Figure(figsize=(12, 6)); axs = fig.subplots(2, 1)
    for r in (est, val):
        ok, lev, ex = excess(r, est)
        for sgn, mk in ((1, 'o'), (-1, 's')):
            m = ok & (np.sign(LEVELS[lev]) == sgn)
            # 0.5 s bins
            tb = np.arange(0, 25, 0.5)
            idx = np.digitize(r.t[m], tb)
            mu = [ex[m][idx == i].mean() * sgn if np.any(idx == i) else np.nan for i in range(1, tb.size)]
            axs[0].plot(tb[:-1] + 0.25, mu, mk, label=f"{r.name} dir {sgn:+d}")
    axs[0].set_xlabel('t (s)'); axs[0].set_ylabel('friction excess vs est map (N)'); axs[0].legend(fontsize=7)
    ok, lev, ex = excess(val, est)
    edges = np.flatnonzero(np.diff(val.pulses) != 0)
    last = np.full(val.t.size, np.nan)
    j = 0
    for k in range(val.t.size):
        while j < edges.size and edges[j] < k:
            j += 1
        if j > 0:
            last[k] = (k - edges[j - 1]) * DT
    sg = np.sign(LEVELS[lev])
    axs[1].plot(last[ok], ex[ok] * sg[ok], '.', ms=1)
    axs[1].set_xlabel('time since last pulse edge (s)'); axs[1].set_ylabel('friction excess (N)')
    for lo, hi in ((0.15, 0.25), (0.25, 0.35), (0.35, 0.5)):
        m = ok & (last >= lo) & (last < hi)
        print(f"since edge {lo}-{hi}s: excess {np.mean(ex[m]*sg[m]):.2f} N (n={m.sum()})")
    fig.tight_layout(); fig.savefig('friction_excess.png', dpi=70)
