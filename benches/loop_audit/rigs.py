"""Independent closed-loop servo-axis simulator for auditing `gmsfric loop`.

Written from the effect *names* only (docs/loop.md "Effect catalogue"); nothing in here is taken
from the project's own rig generators.

Plant
-----
* Motor mass (or inertia) ``Mm`` with the encoder on it; optionally (``compliance``) a load
  ``Ml = r Mm`` on a spring-damper behind it (two-mass, resonance ``fn``, damping ratio ``zeta``).
* Friction on the motor, *smoothed Coulomb + viscous*:
      F(v) = s(q, t, h) [Fc_t + (Fs - Fc) exp(-(v/vs)^2)] tanh(v / eps) + Fv v + a_v Fv |v| + Maxwell-slip
  with ``eps = 1e-4 * vmax`` (very small velocity scale).  ``s`` carries position-dependent
  friction, drift and heating multipliers.  ``Fc_t`` is the part of the Coulomb level carried by
  the tanh; with pre-sliding planted, a share of Fc is moved into Maxwell-slip elements (elastic
  up to a break displacement Delta_i, then slipping at F_i), so the sliding level stays Fc.
* Integration: fixed step ``dt = 1/20000 s`` (20 kHz).  Velocity is advanced *implicitly*
  (backward Euler, scalar monotone equation solved by safeguarded Newton/bisection, which
  keeps the stiff tanh stable), position explicitly with the new velocity (symplectic
  Euler); spring, Maxwell-slip, position force and the load mass are explicit (their
  omega*dt is checked to stay < 0.3).
* Input delay: the drive applies the controller output ``tau`` seconds after it is computed and
  logged (ring buffer in internal steps).

Controller (5 kHz, ZOH, on the quantized encoder position)
--------------------------------------------------------
* ``pid``: u = Kp e + Ki int e + Kd d/dt(e) with first-order derivative filter.
* ``cascade``: P position loop -> PI velocity loop (velocity from filtered encoder difference).
* optional feedforward ``Mhat a_ref + Fvhat v_ref``; optional symmetric drive limit with
  conditional-integration anti-windup.

Logging
-------
Point-sampled at ``fs_log`` (500-2500 Hz): time, quantized position (encoder step), the
controller output (what was commanded at that instant; after the drive limit) plus white noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, asdict

import numpy as np
from numba import njit

F_INT = 20000.0          # internal integration rate (Hz)
F_CTRL = 5000.0          # controller rate (Hz)
N_SUB = int(F_INT / F_CTRL)


@dataclass
class Rig:
    rotary: bool
    M: float               # total mass/inertia (motor + load)
    Fc: float
    Fv: float
    offset: float
    enc: float             # encoder step (m or rad)
    noise: float           # force noise std (N or N m)
    vmax: float            # design top speed
    travel: float          # usable travel (m or rad), centred at 0
    fs_log: float
    ctrl: str              # 'pid' | 'cascade'
    fb: float              # closed-loop bandwidth (Hz)
    ff: bool
    drive_limit: float     # 0 = none
    # planted effects (zero = absent)
    asym: float = 0.0                   # viscous Fv(1 +/- asym)
    fs_ratio: float = 0.0               # Stribeck Fs/Fc - 1 (0 = none)
    vs: float = 1.0
    ms_delta: list = field(default_factory=list)   # Maxwell-slip break displacements
    ms_force: list = field(default_factory=list)   # Maxwell-slip break forces
    pdf_amp: float = 0.0                # position dependent friction amplitude (fraction of Fc)
    pdf_kind: int = 0                   # 1 sine, 2 linear ramp
    pdf_period: float = 1.0
    pdf_phase: float = 0.0
    pf_kind: int = 0                    # 1 cogging sine, 2 spring, 3 gravity sin(q)
    pf_amp: float = 0.0
    pf_period: float = 1.0
    pf_phase: float = 0.0
    delay: float = 0.0                  # input delay (s)
    drift_amp: float = 0.0              # friction multiplier 1 + d h(t)
    drift_kind: int = 0                 # 1 linear t/T, 2 1-exp(-t/tau)
    drift_tau: float = 1.0
    heat_amp: float = 0.0               # friction multiplier 1 - h m/vref, m = LP(|v|)
    heat_tau: float = 1.0
    comp_ratio: float = 0.0             # Ml / Mm
    comp_fn: float = 0.0
    comp_zeta: float = 0.05

    def to_dict(self):
        return asdict(self)


@njit(cache=True)
def _fric(v, q, t, hstate, p, Fscale):
    # returns friction force (without Maxwell-slip) and its derivative w.r.t. v
    Fc_t, Fv, asym, dS, vs, eps = p[0], p[1], p[2], p[3], p[4], p[5]
    th = math.tanh(v / eps)
    ex = math.exp(-(v / vs) ** 2) if dS != 0.0 else 0.0
    lev = Fscale * (Fc_t + dS * ex)
    dlev = Fscale * dS * ex * (-2.0 * v / (vs * vs))
    sgn = 1.0 if v >= 0 else -1.0
    F = lev * th + Fscale * Fv * (v + asym * abs(v))
    dF = dlev * th + lev * (1.0 - th * th) / eps + Fscale * Fv * (1.0 + asym * sgn)
    return F, dF


@njit(cache=True)
def _simulate(r_q, r_v, r_a, pars, ms_d, ms_k, n_log_sub, T_end, seed_noise):
    # pars layout (see simulate())
    (Mm, Ml, kspr, cspr, Fc_t, Fv, asym, dS, vs, eps, offset, enc,
     pdf_amp, pdf_kind, pdf_period, pdf_phase, pf_kind, pf_amp, pf_period, pf_phase,
     delay_steps, drift_amp, drift_kind, drift_tau, heat_amp, heat_tau, vref,
     ctrl, Kp, Ki, Kd, tau_d, Kpp, Kv, wi, tau_v, ff, Mhat, Fvhat, ulim, travel) = (
        pars[0], pars[1], pars[2], pars[3], pars[4], pars[5], pars[6], pars[7], pars[8],
        pars[9], pars[10], pars[11], pars[12], pars[13], pars[14], pars[15], pars[16],
        pars[17], pars[18], pars[19], pars[20], pars[21], pars[22], pars[23], pars[24],
        pars[25], pars[26], pars[27], pars[28], pars[29], pars[30], pars[31], pars[32],
        pars[33], pars[34], pars[35], pars[36], pars[37], pars[38], pars[39], pars[40])
    dt = 1.0 / 20000.0
    dtc = dt * 4
    nsteps = int(T_end / dt)
    nlog = nsteps // n_log_sub
    out_t = np.zeros(nlog)
    out_q = np.zeros(nlog)
    out_u = np.zeros(nlog)
    out_qt = np.zeros(nlog)
    nd = int(delay_steps)
    buf = np.zeros(nd + 1)
    q1 = r_q[0]
    v1 = 0.0
    q2 = q1
    v2 = 0.0
    nms = ms_d.shape[0]
    z = np.zeros(nms)
    hstate = 0.0
    # controller state
    integ = 0.0
    dfilt = 0.0
    e_prev = 0.0
    qm_prev = math.floor(q1 / enc + 0.5) * enc
    vest = 0.0
    u = 0.0
    p = np.array([Fc_t, Fv, asym, dS, vs, eps])
    two_mass = Ml > 0.0
    ilog = 0
    for k in range(nsteps):
        t = k * dt
        if k % 4 == 0:
            kc = k // 4
            if kc >= r_q.shape[0]:
                kc = r_q.shape[0] - 1
            qm = math.floor(q1 / enc + 0.5) * enc
            if ctrl == 0:
                e = r_q[kc] - qm
                draw = (e - e_prev) / dtc if k > 0 else 0.0
                e_prev = e
                dfilt += (draw - dfilt) * dtc / (tau_d + dtc)
                u_un = Kp * e + Ki * integ + Kd * dfilt
            else:
                draw = (qm - qm_prev) / dtc if k > 0 else 0.0
                vest += (draw - vest) * dtc / (tau_v + dtc)
                vr = Kpp * (r_q[kc] - qm) + (r_v[kc] if ff > 0 else 0.0)
                e = vr - vest
                u_un = Kv * (e + wi * integ)
            qm_prev = qm
            if ff > 0:
                u_un += Mhat * r_a[kc] + Fvhat * r_v[kc]
            u = u_un
            sat = False
            if ulim > 0.0:
                if u > ulim:
                    u = ulim
                    sat = True
                elif u < -ulim:
                    u = -ulim
                    sat = True
            if not sat:
                integ += e * dtc
            if k % n_log_sub == 0 and ilog < nlog:
                out_t[ilog] = t
                out_q[ilog] = qm
                out_u[ilog] = u
                out_qt[ilog] = q1
                ilog += 1
        elif k % n_log_sub == 0 and ilog < nlog:
            # (n_log_sub is a multiple of 4, never here)
            pass
        # delay line (internal steps)
        if nd > 0:
            ua = buf[k % (nd + 1)]
            buf[k % (nd + 1)] = u
            if k < nd:
                ua = 0.0
        else:
            ua = u
        # friction multipliers
        s = 1.0
        if pdf_kind == 1:
            s *= 1.0 + pdf_amp * math.sin(2 * math.pi * q1 / pdf_period + pdf_phase)
        elif pdf_kind == 2:
            s *= 1.0 + pdf_amp * (2.0 * q1 / travel)
        if drift_kind == 1:
            s *= 1.0 + drift_amp * (t / T_end)
        elif drift_kind == 2:
            s *= 1.0 + drift_amp * (1.0 - math.exp(-t / drift_tau))
        if heat_amp != 0.0:
            s *= 1.0 - heat_amp * min(hstate / vref, 1.5)
        # external forces (explicit)
        fext = offset
        if pf_kind == 1:
            fext += pf_amp * math.sin(2 * math.pi * q1 / pf_period + pf_phase)
        elif pf_kind == 2:
            fext += pf_amp * (2.0 * q1 / travel)
        elif pf_kind == 3:
            fext += pf_amp * math.sin(q1 + pf_phase)
        fms = 0.0
        for i in range(nms):
            fms += ms_k[i] * z[i]
        fspr = 0.0
        if two_mass:
            fspr = kspr * (q1 - q2) + cspr * (v1 - v2)
        # implicit velocity: a v + F(v) = rhs
        a = Mm / dt
        rhs = a * v1 + ua - fext - fms - fspr
        # bracket
        F0, dF0 = _fric(v1, q1, t, hstate, p, s)
        g0 = a * v1 + F0 - rhs
        d = abs(g0) / a + 1e-12
        lo = v1
        hi = v1
        if g0 > 0:
            lo = v1 - d
            while True:
                Fl, _ = _fric(lo, q1, t, hstate, p, s)
                if a * lo + Fl - rhs <= 0:
                    break
                d *= 2.0
                lo = v1 - d
        else:
            hi = v1 + d
            while True:
                Fh, _ = _fric(hi, q1, t, hstate, p, s)
                if a * hi + Fh - rhs >= 0:
                    break
                d *= 2.0
                hi = v1 + d
        v = 0.5 * (lo + hi)
        for it in range(80):
            Fv_, dFv_ = _fric(v, q1, t, hstate, p, s)
            g = a * v + Fv_ - rhs
            if g > 0:
                hi = v
            else:
                lo = v
            dv = g / (a + dFv_)
            vn = v - dv
            if vn <= lo or vn >= hi:
                vn = 0.5 * (lo + hi)
            if abs(vn - v) < 1e-14 + 1e-12 * abs(v):
                v = vn
                break
            v = vn
        dq = v * dt
        v1 = v
        q1 += dq
        for i in range(nms):
            zi = z[i] + dq
            if zi > ms_d[i]:
                zi = ms_d[i]
            elif zi < -ms_d[i]:
                zi = -ms_d[i]
            z[i] = zi
        if two_mass:
            a2 = (kspr * (q1 - q2) + cspr * (v1 - v2)) / Ml
            v2 += a2 * dt
            q2 += v2 * dt
        if heat_amp != 0.0:
            hstate += (abs(v1) - hstate) * dt / heat_tau
        if not (abs(q1) < 1e6):
            break
    return out_t[:ilog], out_q[:ilog], out_u[:ilog], out_qt[:ilog]


# ----------------------------------------------------------------------------- trajectories

def _derivs(q, dt):
    v = np.gradient(q, dt)
    a = np.gradient(v, dt)
    return v, a


def traj_random(rng, T, travel, vmax, fmax=None):
    """Smoothed random reference: a slow band (0.03-0.25 Hz, covering the travel) plus a faster
    band (0.3-fmax Hz, fmax 0.8-2 Hz) that adds reversals; sums of sinusoids with random phases,
    each band carrying about half the top speed."""
    dtc = 1.0 / F_CTRL
    t = np.arange(int(T * F_CTRL) + 8) * dtc
    fmax = fmax or rng.uniform(0.8, 2.0)

    def band(f0, f1):
        fr = np.linspace(f0, f1, 15)
        ph = rng.uniform(0, 2 * np.pi, fr.size)
        amp = rng.uniform(0.5, 1.0, fr.size) / fr
        x = (amp[:, None] * np.sin(2 * np.pi * fr[:, None] * t[None, :] + ph[:, None])).sum(0)
        return x - x.mean()

    slow, fast = band(0.03, 0.25), band(0.3, fmax)
    slow *= 0.35 * travel / np.abs(slow).max()
    slow *= min(1.0, 0.5 * vmax / np.abs(np.gradient(slow, dtc)).max())
    fast *= 0.5 * vmax / np.abs(np.gradient(fast, dtc)).max()
    q = slow + fast
    q *= min(1.0, 0.45 * travel / np.abs(q).max())
    # ramp in from 0 over 0.3 s
    w = np.clip(t / 1.0, 0, 1)
    w = w * w * (3 - 2 * w)
    q = q * w
    q *= min(1.0, vmax / np.abs(np.gradient(q, dtc)).max())
    v, a = _derivs(q, dtc)
    return q, v, a


def traj_sweep(rng, T, travel, vmax):
    """Sinusoidal sweep (chirp) with amplitude limited by vmax, centred in the travel."""
    dtc = 1.0 / F_CTRL
    t = np.arange(int(T * F_CTRL) + 8) * dtc
    f0, f1 = rng.uniform(0.1, 0.25), rng.uniform(0.8, 2.0)
    f = f0 * (f1 / f0) ** (t / T)
    ph = 2 * np.pi * np.cumsum(f) * dtc
    A = np.minimum(0.45 * travel, vmax / (2 * np.pi * f))
    w = np.clip(t / 0.5, 0, 1)
    q = A * np.sin(ph) * w * w * (3 - 2 * w)
    v, a = _derivs(q, dtc)
    return q, v, a


def traj_trapezoid(rng, T, travel, vmax, amax):
    """Point-to-point moves with trapezoid velocity and dwells, alternating directions."""
    dtc = 1.0 / F_CTRL
    n = int(T * F_CTRL) + 8
    q = np.zeros(n)
    pos = 0.0
    k = 0
    side = rng.choice([-1.0, 1.0])
    while k < n:
        # dwell
        nd = int(rng.uniform(0.15, 0.5) * F_CTRL)
        q[k:k + nd] = pos
        k += nd
        if k >= n:
            break
        target = side * rng.uniform(0.1, 0.45) * travel
        side = -side
        if rng.random() < 0.25:   # sometimes a short move in the same direction
            target = pos + np.sign(target - pos) * rng.uniform(0.02, 0.1) * travel
            target = float(np.clip(target, -0.45 * travel, 0.45 * travel))
        D = target - pos
        L = abs(D)
        vm = vmax * rng.uniform(0.3, 1.0)
        if L < vm * vm / amax:
            vm = math.sqrt(L * amax)
        ta = vm / amax
        tc = L / vm - ta if vm > 0 else 0
        Tm = 2 * ta + tc
        tt = np.arange(int(Tm * F_CTRL) + 1) * dtc
        s = np.where(tt < ta, 0.5 * amax * tt ** 2,
                     np.where(tt < ta + tc, 0.5 * amax * ta ** 2 + vm * (tt - ta),
                              L - 0.5 * amax * np.clip(Tm - tt, 0, None) ** 2))
        seg = pos + np.sign(D) * s
        m = min(seg.size, n - k)
        q[k:k + m] = seg[:m]
        k += m
        pos = target
    v, a = _derivs(q, dtc)
    return q, v, a


def make_traj(kind, rng, rig: Rig, T):
    amax = rig.vmax * rng.uniform(4.0, 10.0)
    if kind == "random":
        return traj_random(rng, T, rig.travel, rig.vmax)
    if kind == "sweep":
        return traj_sweep(rng, T, rig.travel, rig.vmax)
    if kind == "trapezoid":
        return traj_trapezoid(rng, T, rig.travel, rig.vmax, amax)
    raise ValueError(kind)


# ----------------------------------------------------------------------------- simulate

def simulate(rig: Rig, traj, T, seed):
    r_q, r_v, r_a = traj
    rng = np.random.default_rng(seed)
    M = rig.M
    if rig.comp_ratio > 0:
        Mm = M / (1 + rig.comp_ratio)
        Ml = M - Mm
        w = 2 * np.pi * rig.comp_fn
        mu = Mm * Ml / M
        kspr = w * w * mu
        cspr = 2 * rig.comp_zeta * w * mu
    else:
        Mm, Ml, kspr, cspr = M, 0.0, 0.0, 0.0
    ms_d = np.asarray(rig.ms_delta, float)
    ms_F = np.asarray(rig.ms_force, float)
    ms_k = ms_F / ms_d if ms_d.size else np.zeros(0)
    dt = 1.0 / F_INT
    if ms_k.size:
        wdt = math.sqrt(ms_k.sum() / Mm) * dt
        assert wdt < 0.3, f"Maxwell-slip too stiff for dt: omega dt = {wdt}"
    Fc_t = rig.Fc - ms_F.sum()
    dS = rig.fs_ratio * rig.Fc
    eps = 1e-4 * rig.vmax
    wb = 2 * np.pi * rig.fb
    if rig.ctrl == "pid":
        ctrl = 0
        Kp = M * wb * wb
        Kd = 2 * 0.8 * M * wb
        Ki = Kp * wb / 6
        tau_d = 1.0 / (2 * np.pi * 8 * rig.fb)
        Kpp = Kv = wi = tau_v = 0.0
    else:
        ctrl = 1
        Kpp = wb
        wv = 4 * wb
        Kv = M * wv
        wi = wv / 5
        tau_v = 1.0 / (2 * np.pi * 10 * rig.fb)
        Kp = Ki = Kd = tau_d = 0.0
    vref = 0.5 * rig.vmax
    delay_steps = int(round(rig.delay * F_INT))
    n_log_sub = int(round(F_INT / rig.fs_log))
    assert n_log_sub % N_SUB == 0
    Mhat = M * rng.uniform(0.8, 1.0)
    Fvhat = rig.Fv * rng.uniform(0.5, 1.0)
    pars = np.array([
        Mm, Ml, kspr, cspr, Fc_t, rig.Fv, rig.asym, dS, rig.vs, eps, rig.offset, rig.enc,
        rig.pdf_amp, rig.pdf_kind, rig.pdf_period, rig.pdf_phase,
        rig.pf_kind, rig.pf_amp, rig.pf_period, rig.pf_phase,
        delay_steps, rig.drift_amp, rig.drift_kind, rig.drift_tau, rig.heat_amp, rig.heat_tau,
        vref, ctrl, Kp, Ki, Kd, tau_d, Kpp, Kv, wi, tau_v, 1.0 if rig.ff else 0.0, Mhat, Fvhat,
        rig.drive_limit, rig.travel], float)
    t, q, u, qt = _simulate(r_q, r_v, r_a, pars, ms_d, ms_k, n_log_sub, T, seed)
    f = u + rng.normal(0.0, rig.noise, u.size)
    return dict(t=t, q=q, f=f, u=u, q_true=qt, ref=r_q[::int(F_CTRL / rig.fs_log)][:t.size])


# ----------------------------------------------------------------------------- effect size

def own_force(rig: Rig, eff: str, d):
    """The planted effect's own force along the simulated run (true position, log rate), i.e.
    the force with the effect minus the force without it at the same motion.  Delay: u(t) -
    u(t - tau) of the noise-free command.  Compliance: not available here (None)."""
    q, t = d["q_true"], d["t"]
    v = np.gradient(q, t)
    sg = np.tanh(v / (1e-4 * rig.vmax))
    T = t[-1] if t.size else 1.0
    if eff == "asymmetric_friction":
        return rig.asym * rig.Fv * np.abs(v)
    if eff == "stribeck":
        return rig.fs_ratio * rig.Fc * np.exp(-(v / rig.vs) ** 2) * sg
    if eff == "position_dependent_friction":
        if rig.pdf_kind == 1:
            s = rig.pdf_amp * np.sin(2 * np.pi * q / rig.pdf_period + rig.pdf_phase)
        else:
            s = rig.pdf_amp * 2 * q / rig.travel
        return rig.Fc * s * sg
    if eff == "position_dependent_force":
        if rig.pf_kind == 1:
            return rig.pf_amp * np.sin(2 * np.pi * q / rig.pf_period + rig.pf_phase)
        if rig.pf_kind == 2:
            return rig.pf_amp * 2 * q / rig.travel
        return rig.pf_amp * np.sin(q + rig.pf_phase)
    if eff in ("friction_drift", "heating"):
        if eff == "friction_drift":
            h = t / T if rig.drift_kind == 1 else 1 - np.exp(-t / rig.drift_tau)
            s = rig.drift_amp * h
        else:
            m = np.zeros_like(v)
            dt = np.diff(t, prepend=t[0])
            for i in range(1, v.size):
                m[i] = m[i - 1] + (abs(v[i]) - m[i - 1]) * dt[i] / rig.heat_tau
            s = -rig.heat_amp * np.minimum(m / (0.5 * rig.vmax), 1.5)
        return s * (rig.Fc * sg + rig.Fv * v)
    if eff == "presliding_hysteresis":
        F = np.zeros_like(q)
        for dlt, w in zip(rig.ms_delta, rig.ms_force):
            z = 0.0
            for i in range(1, q.size):
                z = min(max(z + q[i] - q[i - 1], -dlt), dlt)
                F[i] += w / dlt * z
        return F - sum(rig.ms_force) * sg
    if eff == "input_delay":
        n = int(round(rig.delay * rig.fs_log))
        u = d["u"]
        return np.r_[np.zeros(n), u[n:] - u[:-n]] if n else np.zeros_like(u)
    return None
