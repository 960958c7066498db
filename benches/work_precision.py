"""Work-precision on a stiff axis: error against a fine reference vs wall time.

    python benches/work_precision.py            # full table (~2-4 min, one process)
    python benches/work_precision.py --quick    # fewer points

The system (continuous time, SI): a light axis ``m x'' = u - F`` (m = 0.5 kg, no delay), a
continuous PID ``u = kp e + ki int(e) + kd d/dt e`` with a first-order derivative filter (tf),
tracking a 1 mm, 5 Hz sine (reversals every 0.1 s), and a 4-block GMS with stiff blocks
(k = 1e7 N/m each: pre-sliding oscillation sqrt(4e7/0.5) ~ 8.9e3 rad/s) and fast slip relaxation
(c / s ~ 7e4 1/s, time slip law), Stribeck curve fc = 10 N, fs = 15 N, vs = 2 mm/s.

Methods (each converges to that system):

- gmsfric ``simulate_closed_loop`` at step dt: discrete PID at dt (backward Euler, what
  ``gmsfric.PID`` is), exact ZOH plant, GMS updated exactly over each step, linearly implicit
  coupling;
- a numba explicit loop at step dt, written like ``numba_axis.py`` (the velocity at the start of
  the step drives the blocks: stick ``F += k v dt`` up to the break force, slip relaxes
  exactly ``exp(-c dt / s)``; the plant is exact ZOH with the friction held), with the same
  discrete PID as gmsfric: the two differ only in the friction coupling.  One rule differs
  from ``numba_axis.py``: a sticking block breaks away only when its force *along the motion*
  reaches ``alpha_i s(v)`` (the GMS rule gmsfric implements).  ``numba_axis.py`` clamps ``|F_i|``
  in either direction, so a block still opposing the motion is cut to ``alpha_i s(v)`` when
  ``s`` drops (Stribeck) -- a different model: on this axis that loop converges (dt -> 0) to a
  solution 5e-7 m (0.3 % of the tracking error) away from gmsfric's; ``--numba-axis-rule``
  shows it;
- scipy ``solve_ivp`` (Radau, LSODA) on the continuous ODE with the GMS right-hand side
  regularised as an ODE solver needs it (``sign(v) -> tanh(v / v_eps)``, stick/slip switch
  smoothed over ``F_eps``), several tolerances.  The switch is memoryless (a block slips while
  its force along the motion is at its break force): a slipping block whose break force rises
  re-sticks instead of relaxing up at ``c / s`` as in the hybrid GMS, so over reversals this
  ODE converges to a solution ~6e-7 m from gmsfric's, whatever the tolerance.

Reference: gmsfric at dt = 5e-8 s; cross-checked against gmsfric at 1e-7 (step convergence) and
against Radau at rtol 1e-10 on the first 60 ms, which contain the first reversal (the
regularisation's own error shows there).  Error: max |x - x_ref| over the samples every 1e-4 s
(every dt when coarser; m), also as a fraction of the max tracking error.  The table at the end
interpolates each method's time at equal error (log-log) and prints the time ratios.

``--mass 0.05`` runs the same loop on a 10x lighter axis (forces scaled, block stiffness not):
the explicit coupling's step limit ``2 / sqrt(sum k / m)`` drops below 1e-4 s.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass

import numpy as np

import gmsfric as g

MASS = 0.5
FC, FS, VS, DELTA = 10.0, 15.0, 2e-3, 1.0
K_BLOCK = np.array([1e7, 1e7, 1e7, 1e7])
ALPHA = np.array([0.1, 0.2, 0.3, 0.4])
C_SLIP = 1e6  # N/s: relaxation rate c / s(v) between 6.7e4 and 1e5 1/s
SIGMA = 20.0
KP, KI, KD, TF = 1.0e5, 6.0e6, 440.0, 1e-4
AMP, FREQ = 1e-3, 5.0
T_END = 0.2
SAMPLE = 1e-4  # error evaluated every 0.1 ms


def scale_mass(mass: float) -> None:
    """Same closed loop on a lighter/heavier axis: every force (gains, friction levels, slip
    attraction, viscous) scales with the mass, the block stiffness does not -- so only the
    pre-sliding oscillation sqrt(sum k / m) changes (explicit steps must shrink with it)."""
    global MASS, FC, FS, C_SLIP, SIGMA, KP, KI, KD
    r = mass / MASS
    MASS, FC, FS, C_SLIP, SIGMA, KP, KI, KD = mass, FC * r, FS * r, C_SLIP * r, SIGMA * r, KP * r, KI * r, KD * r


def reference(t: np.ndarray) -> np.ndarray:
    return AMP * np.sin(2 * np.pi * FREQ * t)


def gmsfric_model() -> tuple[g.Plant, g.GMS, g.PID]:
    gms = g.GMS(g.Stribeck(FC, FS, VS, DELTA), K_BLOCK, ALPHA, C_SLIP, SIGMA)
    return g.Plant.from_mass(MASS), gms, g.PID(KP, KI, KD, TF)


def run_gmsfric(dt: float, t_end: float = T_END) -> tuple[np.ndarray, np.ndarray]:
    """Positions at the samples every SAMPLE s, and the time grid."""
    plant, gms, pid = gmsfric_model()
    n = int(round(t_end / dt)) + 1
    t = np.arange(n) * dt
    stride = max(1, int(round(SAMPLE / dt)))
    # The same output as the numba loop: the position at the samples, nothing else.
    res = g.simulate_closed_loop(plant, gms, pid, reference(t), dt, record=("position",), every=stride)
    return res.position, t[::stride]


def make_numba_explicit():
    import numba

    @numba.njit(cache=True)
    def run(n, dt, phi, gam, kp, ki, kd, tf, amp, freq, alpha, k, c, fc, fs, vs, sigma, mass, stride, along_only):
        nb = alpha.size
        F = np.zeros(nb)
        stick = np.ones(nb, dtype=np.bool_)
        x0 = 0.0
        x1 = 0.0
        integ = 0.0
        deriv = 0.0
        eprev = 0.0
        out = np.empty(n // stride + 1)
        d_keep = tf / (tf + dt)
        d_gain = kd / (tf + dt)
        for j in range(n):
            r = amp * np.sin(2 * np.pi * freq * j * dt)
            e = r - x0
            if j == 0:
                eprev = e
            deriv = d_keep * deriv + d_gain * (e - eprev)
            eprev = e
            integ += ki * e * dt
            u = kp * e + integ + deriv
            v = x1
            s = fc + (fs - fc) * np.exp(-abs(v / vs))
            Ft = sigma * v
            decay = np.exp(-c / s * dt)
            for i in range(nb):
                if stick[i]:
                    F[i] += k[i] * v * dt
                    lim = alpha[i] * s
                    if abs(F[i]) > lim and (F[i] * v > 0 or not along_only):
                        F[i] = lim if F[i] > 0 else -lim
                        stick[i] = False
                else:
                    if v == 0.0 or F[i] * v < 0:
                        stick[i] = True
                        F[i] += k[i] * v * dt
                    else:
                        fss = alpha[i] * s * (1.0 if v > 0 else -1.0)
                        F[i] = fss + (F[i] - fss) * decay
                Ft += F[i]
            if j % stride == 0:
                out[j // stride] = x0
            w = u - Ft
            nx0 = phi[0, 0] * x0 + phi[0, 1] * x1 + gam[0] * w
            nx1 = phi[1, 0] * x0 + phi[1, 1] * x1 + gam[1] * w
            x0 = nx0
            x1 = nx1
        return out

    return run


def run_numba(fn, dt: float, along_only: bool = True) -> np.ndarray:
    n = int(round(T_END / dt)) + 1
    phi = np.array([[1.0, dt], [0.0, 1.0]])
    gam = np.array([dt * dt / (2 * MASS), dt / MASS])
    stride = max(1, int(round(SAMPLE / dt)))
    out = fn(n, dt, phi, gam, KP, KI, KD, TF, AMP, FREQ, ALPHA, K_BLOCK, C_SLIP, FC, FS, VS, SIGMA, MASS, stride, along_only)
    return out[: (n - 1) // stride + 1]


@dataclass
class Regularised:
    """The continuous closed loop as an ODE: y = [x, v, int(e), w, F_1..F_N] with the derivative
    filter state w (D = kd (e - w) / tf, dw/dt = (e - w) / tf) and the GMS switch smoothed."""

    v_eps: float = 1e-6  # m/s: sign(v) -> tanh(v / v_eps)
    f_eps_rel: float = 1e-4  # stick/slip switch width, relative to each block's break force

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        x, v, integ, w = y[0], y[1], y[2], y[3]
        F = y[4:]
        e = AMP * math.sin(2 * math.pi * FREQ * t) - x
        u = KP * e + KI * integ + KD * (e - w) / TF
        sgn = math.tanh(v / self.v_eps)
        s = FC + (FS - FC) * math.exp(-abs(v / VS) ** DELTA)
        limit = ALPHA * s
        # slip weight: 1 once the block's force along the motion reaches its break force
        wslip = 0.5 * (1.0 + np.tanh((F * sgn - limit) / (self.f_eps_rel * limit)))
        dF = (1.0 - wslip) * K_BLOCK * v + wslip * (C_SLIP / s) * (limit * sgn - F)
        dy = np.empty_like(y)
        dy[0] = v
        dy[1] = (u - F.sum() - SIGMA * v) / MASS
        dy[2] = e
        dy[3] = (e - w) / TF
        dy[4:] = dF
        return dy


def run_ivp(method: str, rtol: float, t_end: float = T_END):
    from scipy.integrate import solve_ivp

    reg = Regularised()
    t_eval = np.minimum(np.arange(int(round(t_end / SAMPLE)) + 1) * SAMPLE, t_end)
    y0 = np.zeros(4 + K_BLOCK.size)
    # absolute tolerances per state: position ~1e-3 m, velocity ~3e-2 m/s, forces ~10 N
    scale = np.array([1e-3, 3e-2, 1e-4, 1e-3] + [1.0] * K_BLOCK.size)
    sol = solve_ivp(reg.rhs, (0.0, t_end), y0, method=method, t_eval=t_eval, rtol=rtol, atol=rtol * scale)
    if not sol.success:
        raise RuntimeError(f"solve_ivp {method} rtol {rtol}: {sol.message}")
    return sol.y[0], sol.nfev


def timed(fn, repeats: int = 1):
    best, out = math.inf, None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t0)
    return out, best


def equal_error_time(points: list[tuple[float, float]], target: float) -> float:
    """Time to reach error `target`: log-log interpolation along the method's work-precision front
    (the settings no cheaper setting beats in error), between the two front points that bracket
    the target; nan outside the front. `points` are (error, seconds). A method whose error is
    not monotone in its setting (an explicit scheme converging to its own discretisation) is
    credited with its cheapest setting that reaches the target, not with a costlier one."""
    front: list[tuple[float, float]] = []
    for s, e in sorted((s, e) for e, s in points if np.isfinite(e) and e > 0):
        if not front or e < front[-1][1]:
            front.append((s, e))
    for (s0, e0), (s1, e1) in zip(front, front[1:]):
        if e1 <= target <= e0:
            a = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(s0) + a * (math.log(s1) - math.log(s0)))
    return float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer steps and tolerances")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--numba-axis-rule", action="store_true", help="also run the explicit loop with numba_axis.py's break rule")
    ap.add_argument("--mass", type=float, default=MASS, help="axis mass (kg); forces scale with it, block stiffness does not")
    ap.add_argument("--no-ivp", action="store_true", help="skip solve_ivp (slow)")
    args = ap.parse_args(argv)
    scale_mass(args.mass)
    print(f"# mass {MASS:g} kg, blocks {K_BLOCK.size} x {K_BLOCK[0]:.0e} N/m: pre-sliding oscillation "
          f"{math.sqrt(K_BLOCK.sum() / MASS):.3g} rad/s (explicit coupling needs dt < ~{2 / math.sqrt(K_BLOCK.sum() / MASS):.1e} s)")
    load = os.getloadavg()
    print(f"# load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; {os.cpu_count()} logical CPUs; times are best of {args.repeats} "
          "(solve_ivp: one run)")

    ref, t_grid = run_gmsfric(5e-8)
    ref_check, _ = run_gmsfric(1e-7)
    track = np.max(np.abs(reference(t_grid) - ref))
    print(f"# reference: gmsfric dt = 5e-8 s; max tracking error {track:.3e} m; "
          f"|gmsfric(1e-7) - reference| max {np.max(np.abs(ref_check - ref)):.2e} m")
    win = int(round(0.06 / SAMPLE)) + 1
    try:
        if args.no_ivp:
            raise ImportError
        (radau_ref, nfev), secs = timed(lambda: run_ivp("Radau", 1e-10, 0.06))
        print(f"# cross-check: Radau rtol 1e-10 on [0, 0.06] s (regularised GMS): max |x - reference| = "
              f"{np.max(np.abs(radau_ref - ref[:win])):.2e} m ({nfev} rhs calls, {secs:.1f} s)")
    except ImportError:
        print("# scipy not installed: solve_ivp rows skipped")

    rows: dict[str, list[tuple[str, float, float]]] = {"gmsfric": [], "numba explicit": [], "solve_ivp Radau": [], "solve_ivp LSODA": []}

    def err(x: np.ndarray) -> float:
        # x holds samples every max(dt, SAMPLE): compare with the reference at those times
        every = max(1, int(round((ref.size - 1) / max(x.size - 1, 1))))
        r = ref[::every]
        m = min(x.size, r.size)
        d = np.abs(x[:m] - r[:m])
        # an unstable run (explicit coupling beyond its step limit) counts as failed
        return float(np.max(d)) if np.all(np.isfinite(x[:m])) and np.max(d) < 1.0 else float("inf")

    g_steps = [5e-4, 1e-4, 2e-5, 5e-6, 1e-6] if args.quick else [5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6, 5e-7]
    for dt in g_steps:
        try:
            (x, _), secs = timed(lambda: run_gmsfric(dt), args.repeats)
            rows["gmsfric"].append((f"dt {dt:.0e}", err(x), secs))
        except g.SimulationError:
            rows["gmsfric"].append((f"dt {dt:.0e}", float("inf"), float("nan")))
    try:
        fn = make_numba_explicit()
        fn(10, 1e-5, np.eye(2), np.zeros(2), KP, KI, KD, TF, AMP, FREQ, ALPHA, K_BLOCK, C_SLIP, FC, FS, VS, SIGMA, MASS, 1, True)
        n_steps = [5e-4, 1e-4, 2e-5, 5e-6, 1e-6] if args.quick else [5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6, 5e-7, 2e-7, 1e-7]
        for dt in n_steps:
            with np.errstate(all="ignore"):
                x, secs = timed(lambda: run_numba(fn, dt), args.repeats)
            rows["numba explicit"].append((f"dt {dt:.0e}", err(x), secs))
        if args.numba_axis_rule:
            for dt in (1e-5, 1e-6, 1e-7):
                with np.errstate(all="ignore"):
                    x, secs = timed(lambda: run_numba(fn, dt, along_only=False), 1)
                rows.setdefault("numba, numba_axis.py break rule", []).append((f"dt {dt:.0e}", err(x), secs))
    except ImportError:
        print("# numba not installed: numba rows skipped")
    try:
        tols = [] if args.no_ivp else [1e-3, 1e-5, 1e-7] if args.quick else [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8]
        for method in ("Radau", "LSODA"):
            for rtol in tols:
                (x, nfev), secs = timed(lambda: run_ivp(method, rtol))
                rows[f"solve_ivp {method}"].append((f"rtol {rtol:.0e} ({nfev} rhs)", err(x), secs))
    except ImportError:
        pass

    print("\n| method | setting | max position error (m) | error / max tracking error | wall s |")
    print("|---|---|---|---|---|")
    for name, rs in rows.items():
        for setting, e, s in rs:
            print(f"| {name} | {setting} | {e:.2e} | {e / track:.1e} | {s:.4f} |")

    print("\nTime at equal error (log-log interpolation along each method's work-precision front):\n")
    print("| error (m) | gmsfric s | numba explicit s | Radau s | LSODA s | numba / gmsfric | Radau / gmsfric | LSODA / gmsfric |")
    print("|---|---|---|---|---|---|---|---|")
    pts = {k: [(e, s) for _, e, s in v] for k, v in rows.items() if k != "numba, numba_axis.py break rule"}
    for target in (track * 1e-1, track * 1e-2, track * 3e-3, track * 1e-3):
        ts = {k: equal_error_time(v, target) for k, v in pts.items()}
        gt = ts["gmsfric"]
        ratio = lambda k: f"{ts[k] / gt:.1f}" if np.isfinite(ts[k]) and np.isfinite(gt) else "-"  # noqa: E731
        print(f"| {target:.1e} | {gt:.4f} | {ts['numba explicit']:.4f} | {ts['solve_ivp Radau']:.3f} | {ts['solve_ivp LSODA']:.3f} | "
              f"{ratio('numba explicit')} | {ratio('solve_ivp Radau')} | {ratio('solve_ivp LSODA')} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
