"""Position-periodic force ripple: periodogram of the plateau force (minus each plateau's mean)
against position, both runs, per direction. Plateau samples as in friction_excess.py."""
import numpy as np
from matplotlib.figure import Figure
from friction_excess import plateau_mask, LEVELS
from emps import *


def detrended(r):
    ok, lev, v = plateau_mask(r)
    x = r.force.copy()
    for i in range(6):
        m = ok & (lev == i)
        x[m] -= x[m].mean()
    return ok, lev, x


def periodogram(q, x, periods):
    out = []
    for P in periods:
        w = 2 * np.pi * q / P
        A = np.c_[np.cos(w), np.sin(w)]
        c, *_ = np.linalg.lstsq(A, x, rcond=None)
        out.append(np.hypot(*c))
    return np.array(out)


if __name__ == "__main__":
    est, val = runs()
    periods = np.exp(np.linspace(np.log(0.5e-3), np.log(30e-3), 3000))
    fig = Figure(figsize=(12, 6)); axs = fig.subplots(2, 1)
    for j, r in enumerate((est, val)):
        ok, lev, x = detrended(r)
        for sgn in (1, -1):
            m = ok & (np.sign(LEVELS[lev]) == sgn)
            pg = periodogram(r.qm[m], x[m], periods)
            axs[j].semilogx(periods * 1e3, pg, lw=0.7, label=f"dir {sgn:+d}")
            top = np.argsort(pg)[::-1]
            picks = []
            for i in top:
                if all(abs(np.log(periods[i] / p)) > 0.03 for p in picks):
                    picks.append(periods[i])
                if len(picks) == 6:
                    break
            print(r.name, sgn, "peaks (mm, N):", [(round(p * 1e3, 3), round(pg[np.argmin(abs(periods - p))], 2)) for p in picks])
        axs[j].set_xlabel("spatial period (mm)"); axs[j].set_ylabel("amplitude (N)"); axs[j].set_title(r.name); axs[j].legend()
    fig.tight_layout(); fig.savefig("ripple.png", dpi=70)


def phases(P_list=(2.5e-3, 5.43e-3, 1.25e-3)):
    """Cos/sin coefficients of the plateau force at each period, per run, direction and speed."""
    est, val = runs()
    for P in P_list:
        print(f"period {P*1e3:.3f} mm: (a cos, b sin) in N")
        for r in (est, val):
            ok, lev, x = detrended(r)
            for i in range(6):
                m = ok & (lev == i)
                w = 2 * np.pi * r.qm[m] / P
                c, *_ = np.linalg.lstsq(np.c_[np.cos(w), np.sin(w)], x[m], rcond=None)
                print(f"   {r.name[:12]:12s} v={LEVELS[i]:+.3f}: {c[0]:+.2f} {c[1]:+.2f}  |{np.hypot(*c):.2f}|")
