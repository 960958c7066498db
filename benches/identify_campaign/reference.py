"""A direct reference fit of the Maxwell-slip blocks, to show what the pre-sliding data allow.

Not a candidate identifier: it is told where every block is saturated (a turning point after a
swing that breaks every block, known from the experiment's design) and the true number of blocks.
From there it fits the simulated block force along the measured position to the measured force by
least squares on ``(log w_i, log d_i)``, from a few starts (log-spaced and random break
displacements), and keeps the best.  Issue 13 asks that ``identify presliding`` be at least as good
as such a direct fit.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

import sims


def direct_block_fit(x: np.ndarray, F: np.ndarray, n_blocks: int, start: int, sign: float, *, n_starts: int = 6,
                     seed: int = 0) -> dict[str, list[float]]:
    """Blocks ``k1..kN, w1..wN`` (with Jacobian standard errors) from ``x[start:]``, ``F[start:]``,
    all blocks saturated in direction ``sign`` at ``start``."""
    xs, Fs = np.ascontiguousarray(x[start:]), np.ascontiguousarray(F[start:])
    n = n_blocks
    d_hi = 0.5 * float(np.ptp(xs))
    d_lo = max(2e-9, d_hi * 1e-4)

    def resid(q: np.ndarray) -> np.ndarray:
        w, d = np.exp(q[:n]), np.exp(q[n:])
        return sims.maxwell_slip_force(xs, w / d, w, sign * d) - Fs

    rng = np.random.default_rng(seed)
    w0 = np.full(n, 0.5 * float(np.ptp(Fs)) / n)
    starts = [np.geomspace(d_lo * 10, d_hi / 1.5, n)] + [np.sort(np.exp(rng.uniform(np.log(d_lo), np.log(d_hi), n))) for _ in range(n_starts - 1)]
    # bounds keep exp() finite: break forces up to 10x the force span, displacements within the motion
    f_hi = 10.0 * float(np.ptp(Fs))
    lo = np.concatenate([np.full(n, np.log(f_hi * 1e-8)), np.full(n, np.log(d_lo / 10))])
    hi = np.concatenate([np.full(n, np.log(f_hi)), np.full(n, np.log(d_hi * 10))])
    best = None
    for d0 in starts:
        q0 = np.clip(np.concatenate([np.log(w0), np.log(d0)]), lo + 1e-9, hi - 1e-9)
        sol = least_squares(resid, q0, bounds=(lo, hi), method="trf", x_scale=1.0, diff_step=1e-4, max_nfev=400)
        if np.isfinite(sol.cost) and (best is None or sol.cost < best.cost):
            best = sol
    assert best is not None
    q, J, r = best.x, best.jac, best.fun
    dof = max(r.size - 2 * n, 1)
    JtJ = J.T @ J
    cov = np.linalg.pinv(JtJ) * float(r @ r) / dof if np.all(np.isfinite(JtJ)) else np.full((2 * n, 2 * n), np.inf)
    w, d = np.exp(q[:n]), np.exp(q[n:])
    k = w / d
    var_lw, var_ld = np.diag(cov)[:n], np.diag(cov)[n:]
    var_lk = var_lw + var_ld - 2 * np.diag(cov[:n, n:])
    out: dict[str, list[float]] = {}
    for i in np.argsort(d):
        j = len(out) // 2 + 1
        out[f"k{j}"] = [float(k[i]), float(k[i] * np.sqrt(max(var_lk[i], 0.0)))]
        out[f"w{j}"] = [float(w[i]), float(w[i] * np.sqrt(max(var_lw[i], 0.0)))]
    return out
