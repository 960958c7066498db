"""Steady force on each constant-velocity plateau, both runs: how friction differs between runs.

Plateau samples: |a| small (filtered), away from pulse edges (>150 ms) on the pulses run.
"""
import numpy as np
from scipy import signal
from emps import *

def plateau_table(r, guard=0.15):
    b, a = signal.butter(4, 20 / 500)
    qf = signal.filtfilt(b, a, r.qm)
    v = np.gradient(qf, DT); acc = np.gradient(v, DT)
    ok = np.abs(acc) < 0.02
    edges = np.flatnonzero(np.diff(r.pulses) != 0)
    for e in edges:
        ok[e: e + int(guard / DT)] = False
    # also require velocity constant over a window
    out = {}
    levels = np.array([-0.125, -0.085, -0.045, 0.045, 0.085, 0.125])
    for L in levels:
        m = ok & (np.abs(v - L) < 0.012)
        ff = r.force - r.pulses * r.gtau  # force without the injected pulse: the PD part only? no: use total
        out[L] = (m.sum(), v[m].mean(), r.force[m].mean(), r.force[m].std())
    return out

if __name__ == '__main__':
    est, val = runs()
    te, tv = plateau_table(est), plateau_table(val)
    print(" level   n_e   v_e     F_e     |  n_v   v_v     F_v     | dF (N)")
    for L in te:
        a, b = te[L], tv[L]
        print(f"{L:+.3f} {a[0]:5d} {a[1]:+.4f} {a[2]:+7.2f} | {b[0]:5d} {b[1]:+.4f} {b[2]:+7.2f} | {b[2]-a[2]:+.2f}")
    # by cycle: est run per back-and-forth period (6.2 s)
    for r, tab in ((est, te), (val, tv)):
        b, a = signal.butter(4, 20 / 500)
        qf = signal.filtfilt(b, a, r.qm); v = np.gradient(qf, DT); acc = np.gradient(v, DT)
        ok = np.abs(acc) < 0.02
        for e in np.flatnonzero(np.diff(r.pulses) != 0):
            ok[e: e + 150] = False
        print(r.name, 'per cycle, force at +0.125 / -0.125 plateaus:')
        for c in range(4):
            cyc = (r.t >= c * 6.2) & (r.t < (c + 1) * 6.2)
            s = [r.force[ok & cyc & (np.abs(v - L) < 0.012)].mean() for L in (0.125, -0.125, 0.045, -0.045)]
            print('   ', c, np.round(s, 2))

def split_by_pulse():
    est, val = runs()
    r = val
    b, a = signal.butter(4, 20 / 500)
    qf = signal.filtfilt(b, a, r.qm); v = np.gradient(qf, DT); acc = np.gradient(v, DT)
    ok = np.abs(acc) < 0.02
    for e in np.flatnonzero(np.diff(r.pulses) != 0):
        ok[e: e + 150] = False
    print('pulses run plateau force, pulse off / on:')
    for L in (-0.125, -0.085, -0.045, 0.045, 0.085, 0.125):
        m = ok & (np.abs(v - L) < 0.012)
        print(f"  {L:+.3f}  off {r.force[m & (r.pulses == 0)].mean():+7.2f} (n={np.sum(m & (r.pulses == 0))})  on {r.force[m & (r.pulses > 0)].mean():+7.2f} (n={np.sum(m & (r.pulses > 0))})")

if __name__ == '__main__':
    split_by_pulse()
