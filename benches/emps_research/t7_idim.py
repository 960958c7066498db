"""Inverse-model (IDIM-LS, the EMPS recipe) with the terms the closed-loop study pointed at.

Uses the package's recipe (gmsfric.loop.idim: filtering, decimation, least squares). Errors:
100 ||f - f_hat|| / ||f|| on the decimated rows, estimation (in-sample) and pulses (cross-test).
Grid parameters (delay, vs, block displacements) are chosen on the ESTIMATION run only.
"""
import itertools
import numpy as np
from gmsfric.loop import load_axis_data, Signals
from gmsfric.loop.idim import LinearModel, BASE_TERMS, Term, relative_error
from gmsfric.loop.effects import _play, _compliance

D = '/work/shared/data/emps/'
est_d = load_axis_data(D + 'DATA_EMPS.mat', time='t', position='qm', command='vir', gain='gtau')
val_d = load_axis_data(D + 'DATA_EMPS_PULSES.mat', time='t', position='qm', command='vir', gain='gtau')
se = Signals(est_d)
sv = Signals(val_d, q_range=se.q_range)

T_DIR = Term("dir", ("Fv+", "Fv-", "Fc+", "Fc-"), lambda s, h: np.c_[s.qd * (s.qd > 0), s.qd * (s.qd < 0), 1.0 * (s.qd > 0), -1.0 * (s.qd < 0)])


def t_strib(vs, d=2.0):
    return Term("lowspeed", ("dS",), lambda s, h: np.sign(s.qd) * np.exp(-np.abs(s.qd / h[0]) ** h[1]), (vs, d), ("vS", "dSexp"))


def t_blocks(deltas):
    return Term("blocks", tuple(f"w{i}" for i in range(len(deltas))), lambda s, h: np.column_stack([_play(s, d) for d in h]), tuple(deltas), tuple(f"Delta{i}" for i in range(len(deltas))))


def t_ripple(P, nh=1):
    def build(s, h):
        cols = []
        for k in range(1, int(h[1]) + 1):
            w = 2 * np.pi * k * s.q / h[0]
            cols += [np.cos(w), np.sin(w)]
        return np.column_stack(cols)
    return Term("ripple", tuple(f"r{k}{ab}" for k in range(nh) for ab in "ab"), build, (P, nh), ("P", "nh"))


def t_comp(fn, zeta):
    return Term("compliance", ("m_load",), lambda s, h: _compliance(s, h[0], h[1]), (fn, zeta), ("fn", "zeta"))


def score(terms, delay=0.0):
    m = LinearModel(list(terms), delay=delay).fit(se)
    return m, relative_error(se.y, m.predict(se)), relative_error(sv.y, m.predict(sv))


def best_on_est(make_terms, grid, delay):
    best = None
    for g in grid:
        m, e, v = score(make_terms(g), delay)
        if best is None or e < best[1]:
            best = (m, e, v, g)
    return best


def show(name, m, e, v, g=None):
    p = m.params()
    print(f"{name:42s} est {e:.3f} %  cross {v:.3f} %  {'' if g is None else g}")
    print("      ", {k: f"{x['value']:.4g}±{x['std']:.2g}" for k, x in p.items()})


if __name__ == "__main__":
    I = BASE_TERMS["inertia"]
    ref = [I, BASE_TERMS["viscous"], BASE_TERMS["coulomb"], BASE_TERMS["offset"]]
    show("reference", *score(ref))
    show("reference, hold 0.5 ms", *score(ref, 0.5e-3))
    show("dir (= + asymmetry), hold", *score([I, T_DIR], 0.5e-3))
    # delay beyond the hold, chosen on estimation
    delays = np.arange(0.0, 2.01e-3, 0.1e-3)
    m, e, v, g = best_on_est(lambda g: [I, T_DIR], [None], 0.5e-3)
    rows = [(d, *score([I, T_DIR], d)[1:]) for d in delays]
    dbest = min(rows, key=lambda r: r[1])
    print("dir: delay scan (est-chosen) ->", [(round(r[0] * 1e3, 2), round(r[1], 3), round(r[2], 3)) for r in rows[::2]], "best", dbest)
    vsg = np.geomspace(2e-3, 0.06, 16)
    for d in (0.5e-3, dbest[0]):
        show(f"dir + low-speed (neg Stribeck), delay {d*1e3:.1f}ms", *best_on_est(lambda g: [I, T_DIR, t_strib(g)], vsg, d))
    # blocks
    bl = [(dm, dm / 5, dm / 25) for dm in np.geomspace(1e-5, 3e-3, 12)]
    show("dir + 3 blocks, hold", *best_on_est(lambda g: [I, T_DIR, t_blocks(g)], bl, 0.5e-3))
    show("dir + 3 blocks, best delay", *best_on_est(lambda g: [I, T_DIR, t_blocks(g)], bl, dbest[0]))
    show("dir + low-speed + 3 blocks, best delay", *best_on_est(lambda g: [I, T_DIR, t_strib(g[0]), t_blocks(g[1])], list(itertools.product(vsg[::2], bl[::2])), dbest[0]))
    show("dir + ripple 2.5mm, best delay", *score([I, T_DIR, t_ripple(2.5e-3, 2)], dbest[0]))
    show("dir + compliance, best delay", *best_on_est(lambda g: [I, T_DIR, t_comp(*g)], list(itertools.product(np.geomspace(3, 40, 10), (0.05, 0.2, 0.5))), dbest[0]))
