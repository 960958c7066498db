"""Held-out tests (the loop's criteria) for the terms of t7_idim: paired chunk t on the pulses
run (~0.25 s chunks of rows), held-out error change, BIC change on the estimation rows.
Grid parameters chosen on the estimation run; the force aligned half a sample later (hold)."""
import numpy as np
from gmsfric.loop.select import _chunk_t
from t7_idim import *

HOLD = 0.5e-3
CHUNK = 25


def stats(terms_before, terms_after, k_grid=0):
    m0 = LinearModel(list(terms_before), delay=HOLD).fit(se)
    m1 = LinearModel(list(terms_after), delay=HOLD).fit(se)
    r0e, r1e = se.y - m0.predict(se), se.y - m1.predict(se)
    r0v, r1v = sv.y - m0.predict(sv), sv.y - m1.predict(sv)
    n = se.y.size
    k0, k1 = len(m0.param_names), len(m1.param_names) + k_grid
    bic = n * np.log((r1e @ r1e) / (r0e @ r0e)) + (k1 - k0) * np.log(n)
    return {"est": (relative_error(se.y, m0.predict(se)), relative_error(se.y, m1.predict(se))),
            "cross": (relative_error(sv.y, m0.predict(sv)), relative_error(sv.y, m1.predict(sv))),
            "t_heldout": _chunk_t(r0v, r1v, CHUNK), "dBIC": bic, "params": m1.params()}


def pick(make, grid):
    return min(grid, key=lambda g: score(make(g), HOLD)[1])


if __name__ == "__main__":
    I = BASE_TERMS["inertia"]
    ref = [I, BASE_TERMS["viscous"], BASE_TERMS["coulomb"], BASE_TERMS["offset"]]
    dirm = [I, T_DIR]
    vsg = np.geomspace(2e-3, 0.06, 16)
    bl = [(dm, dm / 5, dm / 25) for dm in np.geomspace(1e-5, 3e-3, 12)]
    out = {}
    out["ref -> dir (asymmetry)"] = stats(ref, dirm)
    for d in (1.0, 2.0):
        vs = pick(lambda g: dirm + [t_strib(g, d)], vsg)
        out[f"dir -> + low-speed exp{d:g} (vS={vs*1e3:.1f} mm/s)"] = stats(dirm, dirm + [t_strib(vs, d)], 1)
    vs = pick(lambda g: dirm + [t_strib(g, 2.0)], vsg)
    b = pick(lambda g: dirm + [t_blocks(g)], bl)
    out[f"dir -> + 3 blocks (D={b[0]*1e3:.3f} mm)"] = stats(dirm, dirm + [t_blocks(b)], 1)
    b2 = pick(lambda g: dirm + [t_strib(vs), t_blocks(g)], bl)
    out[f"dir + low-speed -> + 3 blocks (D={b2[0]*1e3:.3f} mm)"] = stats(dirm + [t_strib(vs)], dirm + [t_strib(vs), t_blocks(b2)], 1)
    out["dir + low-speed -> + ripple 2.5 mm"] = stats(dirm + [t_strib(vs)], dirm + [t_strib(vs), t_ripple(2.5e-3, 1)])
    out["dir + low-speed -> + Legendre force deg 4"] = stats(dirm + [t_strib(vs)], dirm + [t_strib(vs), Term("legf", tuple(f"L{i}" for i in range(1, 5)), lambda s, h: np.polynomial.legendre.legvander(np.clip(2 * (s.q - s.q_range[0]) / (s.q_range[1] - s.q_range[0]) - 1, -1, 1), 4)[:, 1:])])
    for k, o in out.items():
        print(f"{k:52s} est {o['est'][0]:.3f}->{o['est'][1]:.3f}  cross {o['cross'][0]:.3f}->{o['cross'][1]:.3f}  t={o['t_heldout']:.2f}  dBIC={o['dBIC']:.0f}")
    print({k: f"{x['value']:.4g}±{x['std']:.2g}" for k, x in out[[k for k in out if 'exp2' in k][0]]["params"].items()})
