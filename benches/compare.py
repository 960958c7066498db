"""gmsfric against pure Python, numpy, numba and scipy's solve_ivp on the same tasks, one process.

    python benches/compare.py                 # full run (10^7 closed-loop steps; ~2-4 min)
    python benches/compare.py --steps 1000000 # quicker

The headline comparison, against the numba loop a competent user writes (``numba_axis.py``), is
``benches/numba_baseline.py``.  This script compares implementations of gmsfric's own algorithm.

Task A: the paper's closed-loop axis -- plant a/(s^2+bs+c) with a 1.29 ms input
delay (exact ZOH, fractional delay), PID with filtered derivative and anti-windup, 4-block GMS
coupled linearly-implicitly -- dt = 1e-4 s, reference 0.2 mm 0.5 Hz sine (no drive saturation).
Two numba versions implement the core's algorithm: "straightforward" is written as the equations
read (a transliteration of gmsfric's algorithm), "hand-mirrored" copies the core's operation
order and caches. Both use the discretisation from ``Plant._native.discretize``; the script
prints the max abs difference of the trajectories (rounding level: the core fuses multiply-adds
and multiplies by reciprocals).
Task B: cost against the number of GMS blocks N (1..64), gmsfric vs numba.
Task C: friction-only GMS over a long measured trajectory (gmsfric, input not copied), and
friction-only LuGre against scipy solve_ivp (LSODA, rtol 1e-6, atol 1e-12 on the bristle state).

Rates are steps (samples) per second; "wall" is the best of the repeats, "cpu" the thread CPU
time of that repeat (robust when other processes share the machine).  Pure Python and numpy
run fewer steps and are extrapolated (per-step cost is constant); this is stated in the table.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import sys
import time

import numpy as np

from gmsfric import GMS, PID, LuGre, Plant, Stribeck, _gmsfric, simulate_closed_loop, simulate_friction

DT = 1e-4
ST = Stribeck(0.1826, 0.210, 0.45e-3, 1.0)
W = np.array([0.0330, 0.0570, 0.0132, 0.0026])
GMS4 = GMS(ST, [3264.7059e3, 8.8941e3, 23.7869e3, 2.6131e3], W / W.sum(), 1 / 0.45e-3, 6.9846)
PLANT = Plant(0.01985, 168.4, 176.8, 1.29e-3, 1.0)
CTRL = PID(5.0e5, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0)


def gms_blocks(n: int) -> GMS:
    """Same as gms_core::reference::gms_with_blocks: k from 1e7 down to 1e4 N/m, equal fractions."""
    k = [1e7 * 10 ** (-3.0 * i / max(n, 1)) for i in range(n)]
    return GMS(ST, k, [1.0 / n] * n, 1 / 0.45e-3, 6.9846)


def reference(n: int) -> np.ndarray:
    return 2e-4 * np.sin(2 * np.pi * 0.5 * np.arange(n) * DT)


def timed(fn, repeats: int):
    """(result, best wall seconds, cpu seconds of that repeat)."""
    best, cpu, out = math.inf, math.inf, None
    for _ in range(repeats):
        out = None
        c0, w0 = time.thread_time(), time.perf_counter()
        out = fn()
        w, c = time.perf_counter() - w0, time.thread_time() - c0
        if w < best:
            best, cpu = w, c
    return out, best, cpu


def loop_args(model: GMS):
    phi, g_old, g_new, g_f, m = PLANT._native.discretize(DT)
    p = CTRL
    return (DT, np.array(phi), np.array(g_old), np.array(g_new), np.array(g_f), m, p.kp, p.ki, p.kd, p.tf, float(p.u_min), float(p.u_max),
            ST.fc, ST.fs, ST.vs, model.c, model.sigma, np.array(model.k), np.array(model.alpha))


def closed_loop_py(ref, dt, phi, gold, gnew, gf, m, kp, ki, kd, tf, umin, umax, fc, fs, vs, c, sigma, k, alpha, np_blocks=False):
    """The core's closed loop, step by step (plain Python floats; ``np_blocks`` vectorises the
    block update with numpy -- the only part of the loop that is data-parallel)."""
    n, nb = len(ref), len(k)
    pos, vel, cmd, fr = np.empty(n), np.empty(n), np.empty(n), np.empty(n)
    phi, gold, gnew, gf = [float(x) for x in phi], [float(x) for x in gold], [float(x) for x in gnew], [float(x) for x in gf]
    if np_blocks:
        forces, mode, k_arr, a_arr = np.zeros(nb), np.zeros(nb), np.asarray(k), np.asarray(alpha)
    else:
        forces, mode, k, alpha = [0.0] * nb, [0.0] * nb, [float(x) for x in k], [float(x) for x in alpha]
    buf, head, nbuf = [0.0] * (m + 2), 0, m + 2
    xp, xv = float(ref[0]), 0.0
    integral = deriv = prev_e = 0.0
    first = True
    inv_vs = 1.0 / vs
    sdt = sigma / dt
    for i in range(n):
        y = xp
        e = float(ref[i]) - y
        prev = e if first else prev_e
        first, prev_e = False, e
        deriv = (tf * deriv + kd * (e - prev)) / (tf + dt)
        trial_i = integral + ki * e * dt
        u = kp * e + trial_i + deriv
        uc = min(max(u, umin), umax)
        if not ((u > umax and e * ki > 0.0) or (u < umin and e * ki < 0.0)):
            integral = trial_i
        u = uc
        head = 0 if head + 1 == nbuf else head + 1
        buf[head] = u
        oldest = 0 if head + 1 == nbuf else head + 1
        nxt = 0 if oldest + 1 == nbuf else oldest + 1
        uo, un = buf[oldest], buf[nxt]
        f0p = phi[0] * xp + phi[1] * xv + gold[0] * uo + gnew[0] * un
        f0v = phi[2] * xp + phi[3] * xv + gold[1] * uo + gnew[1] * un
        if np_blocks:
            ftot = float(forces.sum())
            trial = (f0p - xp) - gf[0] * ftot
            d = 1.0 if trial >= 0.0 else -1.0
            kt = float(k_arr[mode != d].sum()) + sdt
            dx = trial / (1.0 + gf[0] * kt)
            v = dx / dt
            if dx == 0.0:
                mode[:] = 0.0
                f = float(forces.sum())
            else:
                s = fc + (fs - fc) * math.exp(-abs(v * inv_vs))
                decay = math.exp(-(c / max(s, 2.2250738585072014e-308)) * dt)
                target = d * a_arr * s
                relaxed = target + (forces - target) * decay
                stuck = forces + k_arr * dx
                along = mode == d
                breaks = stuck * d >= target * d
                beyond = forces * d >= target * d
                forces = np.where(along | (breaks & beyond), relaxed, np.where(breaks, target, stuck))
                mode = np.where(along | breaks, d, 0.0)
                f = float(forces.sum()) + sigma * v
        else:
            ftot = 0.0
            for fj in forces:
                ftot += fj
            trial = (f0p - xp) - gf[0] * ftot
            d = 1.0 if trial >= 0.0 else -1.0
            kt = 0.0
            for j in range(nb):
                if mode[j] != d:
                    kt += k[j]
            dx = trial / (1.0 + gf[0] * (kt + sdt))
            v = dx / dt
            if dx == 0.0:
                mode = [0.0] * nb
                f = sum(forces)
            else:
                s = fc + (fs - fc) * math.exp(-abs(v * inv_vs))
                decay = math.exp(-(c / max(s, 2.2250738585072014e-308)) * dt)
                tot = 0.0
                for j in range(nb):
                    target = d * alpha[j] * s
                    fj = forces[j]
                    if mode[j] == d:
                        nf = target + (fj - target) * decay
                    else:
                        stuck = fj + k[j] * dx
                        if stuck * d >= target * d:
                            mode[j] = d
                            nf = target + (fj - target) * decay if fj * d >= target * d else target
                        else:
                            mode[j], nf = 0.0, stuck
                    forces[j] = nf
                    tot += nf
                f = tot + sigma * v
        pos[i], vel[i], cmd[i], fr[i] = xp, xv, u, f
        xp = f0p - gf[0] * f
        xv = f0v - gf[1] * f
    return pos, vel, cmd, fr


def make_numba():
    import numba

    @numba.njit(cache=True)
    def closed_loop_nb(ref, dt, phi, gold, gnew, gf, m, kp, ki, kd, tf, umin, umax, fc, fs, vs, c, sigma, k, alpha):
        n, nb = ref.size, k.size
        pos, vel, meas, cmd, fr = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        forces, mode = np.zeros(nb), np.zeros(nb)  # mode: 0 stick, +-1 slipping in that direction
        buf = np.zeros(m + 2)
        head, nbuf = 0, m + 2
        xp, xv = ref[0], 0.0
        integral, deriv, prev_e, first = 0.0, 0.0, 0.0, True
        inv_vs = 1.0 / vs
        for i in range(n):
            y = xp
            e = ref[i] - y
            prev = e if first else prev_e
            first = False
            prev_e = e
            deriv = (tf * deriv + kd * (e - prev)) / (tf + dt)
            trial_i = integral + ki * e * dt
            u = kp * e + trial_i + deriv
            uc = min(max(u, umin), umax)
            if not ((u > umax and e * ki > 0.0) or (u < umin and e * ki < 0.0)):
                integral = trial_i
            u = uc
            head = 0 if head + 1 == nbuf else head + 1
            buf[head] = u
            oldest = 0 if head + 1 == nbuf else head + 1
            nxt = 0 if oldest + 1 == nbuf else oldest + 1
            uo, un = buf[oldest], buf[nxt]
            f0p = phi[0] * xp + phi[1] * xv + gold[0] * uo + gnew[0] * un
            f0v = phi[2] * xp + phi[3] * xv + gold[1] * uo + gnew[1] * un
            ftot = 0.0
            for j in range(nb):
                ftot += forces[j]
            trial = (f0p - xp) - gf[0] * ftot
            d = 1.0 if trial >= 0.0 else -1.0
            kt = 0.0
            for j in range(nb):
                if mode[j] != d:
                    kt += k[j]
            dx = trial / (1.0 + gf[0] * (kt + sigma / dt))
            v = dx / dt
            if dx == 0.0:
                for j in range(nb):
                    mode[j] = 0.0
                f = 0.0
                for j in range(nb):
                    f += forces[j]
            else:
                s = fc + (fs - fc) * math.exp(-abs(v * inv_vs))
                decay = math.exp(-(c / max(s, 2.2250738585072014e-308)) * dt)
                tot = 0.0
                for j in range(nb):
                    target = d * alpha[j] * s
                    fj = forces[j]
                    if mode[j] == d:
                        nf = target + (fj - target) * decay
                    else:
                        stuck = fj + k[j] * dx
                        if stuck * d >= target * d:
                            mode[j] = d
                            nf = target + (fj - target) * decay if fj * d >= target * d else target
                        else:
                            mode[j] = 0.0
                            nf = stuck
                    forces[j] = nf
                    tot += nf
                f = tot + sigma * v
            pos[i], vel[i], meas[i], cmd[i], fr[i] = xp, xv, y, u, f
            xp = f0p - gf[0] * f
            xv = f0v - gf[1] * f
        return pos, vel, meas, cmd, fr

    return closed_loop_nb


def make_numba_plain():
    """The straightforward numba version a user would write from the equations: the same
    algorithm (exact ZOH plant with fractional delay, PID, GMS eqs. 3-5 solved exactly per step,
    linearly implicit coupling), written as the equations read -- each slipping block evaluates
    its own relaxation factor ``exp(-c dt / s)``, the Stribeck curve uses ``**delta`` and
    ``np.sign``, the delay line indexes with ``%``, sums and tangent stiffness are recomputed
    every step -- but with no per-step allocation (scalar plant update)."""
    import numba

    @numba.njit(cache=True)
    def stribeck(v, fc, fs, vs, delta):
        return fc + (fs - fc) * np.exp(-np.abs(v / vs) ** delta)

    @numba.njit(cache=True)
    def closed_loop_plain(ref, dt, phi, gold, gnew, gf, m, kp, ki, kd, tf, umin, umax, fc, fs, vs, delta, c, sigma, k, alpha):
        n, nb = ref.size, k.size
        pos, vel, meas, cmd, fr = np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n)
        F = np.zeros(nb)
        slipping = np.zeros(nb, np.int64)  # 0 sticking, +1 / -1 slipping in that direction
        L = m + 2
        ubuf = np.zeros(L)
        xp, xv = ref[0], 0.0
        integral, deriv, e_prev = 0.0, 0.0, 0.0
        for i in range(n):
            # PID with filtered derivative and conditional-integration anti-windup
            y = xp
            e = ref[i] - y
            if i == 0:
                e_prev = e
            deriv = (tf * deriv + kd * (e - e_prev)) / (tf + dt)
            e_prev = e
            integral_trial = integral + ki * e * dt
            u_raw = kp * e + integral_trial + deriv
            u = min(max(u_raw, umin), umax)
            if not ((u_raw > umax and e * ki > 0) or (u_raw < umin and e * ki < 0)):
                integral = integral_trial
            # input delay of m + frac steps: u[i-m-1] acts during the first part of the step, u[i-m] after
            ubuf[i % L] = u
            u_old = ubuf[(i - m - 1) % L] if i - m - 1 >= 0 else 0.0
            u_new = ubuf[(i - m) % L] if i - m >= 0 else 0.0
            # free response of the exact ZOH plant over the step
            fp = phi[0] * xp + phi[1] * xv + gold[0] * u_old + gnew[0] * u_new
            fv = phi[2] * xp + phi[3] * xv + gold[1] * u_old + gnew[1] * u_new
            # friction coupled linearly-implicitly: tangent stiffness of the blocks that can stick
            trial = (fp - xp) - gf[0] * F.sum()
            d = 1 if trial >= 0 else -1
            K = sigma / dt
            for j in range(nb):
                if slipping[j] != d:
                    K += k[j]
            dx = trial / (1.0 + gf[0] * K)
            v = dx / dt
            # GMS blocks, eqs. 3-5 solved exactly over the step
            if dx == 0.0:
                slipping[:] = 0
                f = F.sum()
            else:
                sv = np.sign(v)
                s = stribeck(v, fc, fs, vs, delta)
                for j in range(nb):
                    target = sv * alpha[j] * s
                    if slipping[j] == sv:
                        F[j] = target + (F[j] - target) * np.exp(-c / s * dt)
                    else:
                        stuck = F[j] + k[j] * dx
                        if (stuck - target) * sv >= 0:
                            slipping[j] = d
                            if (F[j] - target) * sv >= 0:
                                F[j] = target + (F[j] - target) * np.exp(-c / s * dt)
                            else:
                                F[j] = target
                        else:
                            slipping[j] = 0
                            F[j] = stuck
                f = F.sum() + sigma * v
            pos[i], vel[i], meas[i], cmd[i], fr[i] = xp, xv, y, u, f
            xp = fp - gf[0] * f
            xv = fv - gf[1] * f
        return pos, vel, meas, cmd, fr

    return closed_loop_plain


def lugre_rhs_factory(lugre: LuGre, t: np.ndarray, v: np.ndarray):
    st = lugre.stribeck

    def rhs(tt, z):
        vk = v[min(np.searchsorted(t, tt, side="right"), v.size - 1)]  # ZOH velocity over (t[k-1], t[k]]
        g = st.fc + (st.fs - st.fc) * math.exp(-abs(vk / st.vs) ** st.delta)
        return [vk - lugre.sigma0 * abs(vk) * z[0] / g]

    return rhs


def row(name, steps, wall, cpu, base_wall, note=""):
    rate, crate = steps / wall, steps / cpu if cpu > 0 else float("nan")
    ratio = base_wall / (steps / rate) if base_wall else float("nan")
    print(f"| {name:<40} | {rate:>12.3e} | {crate:>12.3e} | {ratio:>10.3g} | {note}")
    return rate


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=10_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--python-steps", type=int, default=50_000)
    ap.add_argument("--friction-samples", type=int, default=10_000_000)
    args = ap.parse_args()
    n = args.steps
    print(f"# gmsfric {_gmsfric.__version__} | Python {platform.python_version()} | numpy {np.__version__} | {platform.machine()} | "
          f"{os.cpu_count()} logical CPUs | {platform.processor() or platform.platform()}")
    try:
        import numba

        closed_loop_nb = make_numba()
        print(f"# numba {numba.__version__}")
    except ImportError:
        closed_loop_nb = None
        print("# numba not installed (pip install 'gmsfric[bench]'): numba rows skipped")

    ref = reference(n)
    la = loop_args(GMS4)
    print(f"\n## A. Closed loop, GMS N=4, dt=1e-4 s, {n:.0e} steps (rate = steps/s; ratio = gmsfric rate / row rate)\n")
    print(f"| {'implementation':<40} | {'wall steps/s':>12} | {'cpu steps/s':>12} | {'gmsfric x':>10} | note")
    print(f"|{'-' * 42}|{'-' * 14}|{'-' * 14}|{'-' * 12}|------")
    res, g_wall, g_cpu = timed(lambda: simulate_closed_loop(PLANT, GMS4, CTRL, ref, DT), args.repeats)
    g_rate = row("gmsfric simulate_closed_loop", n, g_wall, g_cpu, g_wall, f"best of {args.repeats}")

    def vs(name, steps, wall, cpu, note):
        rate = steps / wall
        print(f"| {name:<40} | {rate:>12.3e} | {steps / cpu:>12.3e} | {g_rate / rate:>10.3g} | {note}")

    if closed_loop_nb is not None:
        closed_loop_nb(ref[:1000], *la)  # compile (cached) outside the timing
        out, wall, cpu = timed(lambda: closed_loop_nb(ref, *la), args.repeats)
        diff = max(float(np.max(np.abs(out[0] - res.position))), float(np.max(np.abs(out[4] - res.friction))))
        vs("numba @njit, hand-mirrored core", n, wall, cpu, f"best of {args.repeats}; max |diff| vs gmsfric (position, friction) = {diff:.3g}")
        mirror_wall, mirror_cpu = wall, cpu
        plain = make_numba_plain()
        lp = la[:15] + (ST.delta,) + la[15:]
        plain(ref[:1000], *lp)
        out, wall, cpu = timed(lambda: plain(ref, *lp), args.repeats)
        diff = max(float(np.max(np.abs(out[0] - res.position))), float(np.max(np.abs(out[4] - res.friction))))
        vs("numba @njit, straightforward", n, wall, cpu, f"best of {args.repeats}; max |diff| vs gmsfric (position, friction) = {diff:.3g}")
        print(f"\nRATIO gmsfric / straightforward numba (N=4, {n:.0e} steps): wall {g_rate / (n / wall):.2f}x, cpu {(n / g_cpu) / (n / cpu):.2f}x")
        print(f"RATIO gmsfric / hand-mirrored numba  (N=4, {n:.0e} steps): wall {g_rate / (n / mirror_wall):.2f}x, cpu {(n / g_cpu) / (n / mirror_cpu):.2f}x\n")
    m = min(args.python_steps, n)
    out, wall, cpu = timed(lambda: closed_loop_py(ref[:m], *la), 1)
    diff = float(np.max(np.abs(out[0] - res.position[:m])))
    vs("pure Python loop", m, wall, cpu, f"{m} steps, rate extrapolated; max |diff| = {diff:.3g}")
    m2 = m // 5
    out, wall, cpu = timed(lambda: closed_loop_py(ref[:m2], *la, np_blocks=True), 1)
    diff = float(np.max(np.abs(out[0] - res.position[:m2])))
    vs("Python loop, numpy block update", m2, wall, cpu, f"{m2} steps, extrapolated; max |diff| = {diff:.3g}")
    del res

    print("\n## B. Cost against the number of GMS blocks (closed loop, 10^6 steps)\n")
    print("| N | gmsfric steps/s | ns/step | numba mirrored steps/s | gmsfric / mirrored | numba straightforward steps/s | gmsfric / straightforward |")
    print("|---|---|---|---|---|---|---|")
    nb_steps = min(n, 1_000_000)
    refb = ref[:nb_steps]
    plain = make_numba_plain() if closed_loop_nb is not None else None
    for blocks in (1, 2, 4, 8, 16, 32, 64):
        model = gms_blocks(blocks)
        r, gw, _ = timed(lambda: simulate_closed_loop(PLANT, model, CTRL, refb, DT), args.repeats)
        if closed_loop_nb is not None and plain is not None:
            lab = loop_args(model)
            o, nw, _ = timed(lambda: closed_loop_nb(refb, *lab), args.repeats)
            lpb = lab[:15] + (ST.delta,) + lab[15:]
            o2, pw, _ = timed(lambda: plain(refb, *lpb), args.repeats)
            scale = 1e-12 * np.max(np.abs(r.position))
            np.testing.assert_allclose(o[0], r.position, rtol=0, atol=scale, err_msg=f"mirrored numba differs at N={blocks}")
            np.testing.assert_allclose(o2[0], r.position, rtol=0, atol=scale, err_msg=f"straightforward numba differs at N={blocks}")
            print(f"| {blocks} | {nb_steps / gw:.3e} | {gw / nb_steps * 1e9:.0f} | {nb_steps / nw:.3e} | {nw / gw:.2f} | {nb_steps / pw:.3e} | {pw / gw:.2f} |")
        else:
            print(f"| {blocks} | {nb_steps / gw:.3e} | {gw / nb_steps * 1e9:.0f} | - | - | - | - |")

    print(f"\n## C. Friction only\n")
    ns = args.friction_samples
    t = np.arange(ns) * DT
    x = 1e-5 * np.sin(2 * np.pi * 2.0 * t) + 2e-3 * np.sin(2 * np.pi * 0.05 * t)
    f, w, c = timed(lambda: simulate_friction(GMS4, t, x), args.repeats)
    print(f"gmsfric simulate_friction GMS N=4, {ns:.0e} samples (position input borrowed, not copied): "
          f"{w:.3f} s wall = {ns / w:.3e} samples/s (cpu {ns / c:.3e})")
    lug = LuGre(ST, 1e5, 300.0, 6.98)
    ms = 20_000
    tt, xx = t[:ms], x[:ms]
    fl, lw, lc = timed(lambda: simulate_friction(lug, tt, xx), args.repeats)
    try:
        from scipy.integrate import solve_ivp

        v = np.concatenate(([0.0], np.diff(xx) / np.diff(tt)))
        rhs = lugre_rhs_factory(lug, tt, v)
        sol, sw, sc = timed(lambda: solve_ivp(rhs, (tt[0], tt[-1]), [0.0], method="LSODA", t_eval=tt, rtol=1e-6, atol=1e-12, max_step=DT), 1)
        z = sol.y[0]
        zdot = np.concatenate(([0.0], np.diff(z) / DT))
        f_ivp = lug.sigma0 * z + lug.sigma1 * zdot + lug.sigma2 * v
        rel = float(np.max(np.abs(f_ivp[1:] - fl[1:])) / np.max(np.abs(fl)))
        print(f"LuGre friction only, {ms} samples: gmsfric {ms / lw:.3e} samples/s; scipy solve_ivp (LSODA, rtol 1e-6, max_step dt) "
              f"{ms / sw:.3e} samples/s; ratio {sw / lw:.0f}x; max force difference {rel:.2%} of peak")
    except ImportError:
        print("scipy not installed: solve_ivp row skipped")


if __name__ == "__main__":
    sys.exit(main())
