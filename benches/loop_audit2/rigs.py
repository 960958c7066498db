"""Independent closed-loop servo-axis simulator for the second outside audit of `gmsfric loop`.

Written from physics only (no code of the tool was read).  One rig = one axis with its
contact, its planted effects, its controller and its logger; a case runs the same rig twice
(estimation and validation run) on trajectories that differ in kind or in seed.

Physics (SI: m, kg, N, s -- or rad, kg m^2, N m, s on a rotary axis)
-----------------------------------------------------------------------
motor mass M1 (= M - m2 when a load sits behind a spring), state x, v

    M1 dv/dt = u_applied(t) - F_contact - F_visc - F_elements - G(x) - F0 - F_out - F_load

* contact 'stick'  : set-valued Coulomb friction with a Stribeck bound, integrated by an
                     implicit (Moreau) time step: the velocity is projected to zero whenever
                     the friction bound g(|v|) can hold the axis during the step -> true sticking;
                     the regularisation is the time step (friction = M1 v*/dt inside the band).
* contact 'lugre'  : LuGre bristles, dz/dt = v - sigma0 |v| z / g(v), F = sigma0 z + sigma1 dz/dt,
                     sigma0 so stiff that the bristle range g/sigma0 stays below half an encoder
                     step (not a visible pre-sliding range); bristles and mass by backward Euler
                     with the relaxation rate frozen over the step (stable for any sigma0).
* g(v) = (Fc + (Fs - Fc) S(v/vs)) * c(x, t)  with S = exp(-|v/vs|^1.5) or 1 / (1 + (v/vs)^2)
  (Fs = Fc unless `stribeck` is planted), c = (1 + position profile) (1 + drift h(t)) (1 + heat)
* F_visc = (Fv v + dFv |v|) (1 + drift h(t)) (1 + heat)            (`asymmetric_friction`: dFv)
* F_elements : Maxwell-slip elements (stiffness k_i, break displacement D_i >= 5 encoder steps)
               carrying a share of the Coulomb level (`presliding_hysteresis`); each element
               has a little damping only while it holds
* G(x) : cogging sine / spring / gravity sin(q) / cable  (`position_dependent_force`)
* F0   : constant force (`offset`)
* load : m2 on a spring-damper behind the motor (`compliance`), or behind a gap (backlash,
         outside the catalogue)
* u_applied(t) = u_cmd(t - tau) (`input_delay`), u_cmd a zero-order hold at the control rate
* outside the catalogue: v|v| drag, force ripple periodic in time, friction growing with the
  transmitted force (load-dependent friction), backlash

Controllers run at 1-10 kHz on the quantised encoder position:
 PID (integral + filtered derivative), P-position / PI-velocity cascade, either with
 velocity/acceleration (and sometimes Coulomb) feed-forward whose mass is mis-set by up to 20 %,
 optional drive saturation with conditional-integration anti-windup.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy import signal

# --------------------------------------------------------------------------------------------
# parameter vector layout (one float64 array handed to the numba kernel)
# --------------------------------------------------------------------------------------------
PNAMES = [
    "M1", "Fc", "Fv", "dFv", "dFs", "vs", "sshape",          # sshape 1 exp^1.5, 2 lorentz
    "contact", "sigma0", "sigma1", "pshare",                  # contact 0 stick, 1 lugre
    "pf_kind", "pf_a", "pf_p", "pf_phi", "x_lo", "x_hi",      # position-dependent friction
    "pg_kind", "pg_a", "pg_p", "pg_phi", "pg_x0",             # position-dependent force
    "delay", "dr_kind", "dr_d", "dr_T", "ht_k", "ht_tau", "vmax",
    "m2", "k2", "c2", "gap",
    "offset", "rp_a", "rp_f", "rp_phi", "drag", "loadfric",
    "ctrl", "Tc", "nsub", "kp", "ki", "kd", "tf", "kpp", "kvv", "kiv", "vff",
    "mff", "fvff", "fcff", "umax", "res",
]
PI = {n: i for i, n in enumerate(PNAMES)}
NP = len(PNAMES)


def pack(d: dict) -> np.ndarray:
    p = np.zeros(NP)
    for k, v in d.items():
        if k in PI:
            p[PI[k]] = float(v)
    return p


# indices as module constants for numba
_I = {n: i for n, i in PI.items()}
M1_, FC_, FV_, DFV_, DFS_, VS_, SSH_ = (_I[n] for n in ["M1", "Fc", "Fv", "dFv", "dFs", "vs", "sshape"])
CON_, S0_, S1_, PSH_ = (_I[n] for n in ["contact", "sigma0", "sigma1", "pshare"])
PFK_, PFA_, PFP_, PFPH_, XLO_, XHI_ = (_I[n] for n in ["pf_kind", "pf_a", "pf_p", "pf_phi", "x_lo", "x_hi"])
PGK_, PGA_, PGP_, PGPH_, PGX0_ = (_I[n] for n in ["pg_kind", "pg_a", "pg_p", "pg_phi", "pg_x0"])
DEL_, DRK_, DRD_, DRT_, HTK_, HTT_, VMAX_ = (_I[n] for n in ["delay", "dr_kind", "dr_d", "dr_T", "ht_k", "ht_tau", "vmax"])
M2_, K2_, C2_, GAP_ = (_I[n] for n in ["m2", "k2", "c2", "gap"])
OFF_, RPA_, RPF_, RPPH_, DRAG_, LF_ = (_I[n] for n in ["offset", "rp_a", "rp_f", "rp_phi", "drag", "loadfric"])
CTRL_, TC_, NSUB_, KP_, KI_, KD_, TF_, KPP_, KVV_, KIV_, VFF_ = (
    _I[n] for n in ["ctrl", "Tc", "nsub", "kp", "ki", "kd", "tf", "kpp", "kvv", "kiv", "vff"])
MFF_, FVFF_, FCFF_, UMAX_, RES_ = (_I[n] for n in ["mff", "fvff", "fcff", "umax", "res"])


# --------------------------------------------------------------------------------------------
# force laws shared by the simulator and by truth.py (numpy versions below)
# --------------------------------------------------------------------------------------------
@nb.njit(cache=True)
def _stribeck_shape(v, vs, kind):
    if kind == 1:
        return math.exp(-abs(v / vs) ** 1.5)
    return 1.0 / (1.0 + (v / vs) ** 2)


@nb.njit(cache=True)
def _pf_profile(x, kind, a, per, phi, xlo, xhi):
    """relative change of the Coulomb level along the travel (a times a unit shape)"""
    if kind == 0:
        return 0.0
    xi = 2.0 * (x - xlo) / (xhi - xlo) - 1.0          # -1 .. 1 over the travel
    if xi > 1.5:
        xi = 1.5
    if xi < -1.5:
        xi = -1.5
    if kind == 1:
        return a * math.sin(2.0 * math.pi * x / per + phi)
    if kind == 2:
        return a * xi
    return a * (2.0 * xi * xi - 1.0)


@nb.njit(cache=True)
def _pg_force(x, kind, a, per, phi, x0):
    """position-dependent load force the drive has to supply"""
    if kind == 0:
        return 0.0
    if kind == 1:      # cogging
        return a * math.sin(2.0 * math.pi * x / per + phi)
    if kind == 2:      # spring about x0 (a = force at distance per)
        return a * (x - x0) / per
    if kind == 3:      # gravity on a rotary joint
        return a * math.sin(x + phi)
    # cable / hose: stiffening pull, tanh about x0 over a length per
    return a * math.tanh((x - x0) / per)


@nb.njit(cache=True)
def _sim_kernel(p, r, vr, ar, elk, eld, elc, x0):
    N = r.shape[0]
    Tc = p[TC_]
    nsub = int(p[NSUB_])
    dt = Tc / nsub
    M1 = p[M1_]
    Fc = p[FC_]
    Fv = p[FV_]
    dFv = p[DFV_]
    dFs = p[DFS_]
    vs = p[VS_]
    ssh = int(p[SSH_])
    contact = int(p[CON_])
    s0 = p[S0_]
    s1 = p[S1_]
    psh = p[PSH_]
    pfk = int(p[PFK_])
    pgk = int(p[PGK_])
    delay = p[DEL_]
    drk = int(p[DRK_])
    htk = p[HTK_]
    httau = p[HTT_]
    vmax = p[VMAX_]
    m2 = p[M2_]
    k2 = p[K2_]
    c2 = p[C2_]
    gap = p[GAP_]
    off = p[OFF_]
    rpa = p[RPA_]
    drag = p[DRAG_]
    lf = p[LF_]
    ctrl = int(p[CTRL_])
    res = p[RES_]
    umax = p[UMAX_]
    ne = elk.shape[0]
    zel = np.zeros(ne)

    X = np.empty(N)
    V = np.empty(N)
    U = np.empty(N)
    FR = np.empty(N)     # total friction force at the tick (for checks)
    X2 = np.empty(N)

    x = x0
    v = 0.0
    z = 0.0
    x2 = x0
    v2 = 0.0
    hm = 0.0
    integ = 0.0
    dfilt = 0.0
    vhat = 0.0
    yprev = math.floor(x0 / res + 0.5) * res
    eprev = r[0] - yprev
    Fel = 0.0
    ffric = 0.0
    for k in range(N):
        t = k * Tc
        # ---------------- controller (sampled, quantised encoder) ----------------
        y = math.floor(x / res + 0.5) * res
        e = r[k] - y
        ff = p[MFF_] * ar[k] + p[FVFF_] * vr[k] + p[FCFF_] * math.tanh(vr[k] / (0.01 * vmax))
        if ctrl == 0:
            de = (e - eprev) / Tc
            eprev = e
            dfilt += (de - dfilt) * Tc / (p[TF_] + Tc)
            inew = integ + p[KI_] * e * Tc
            u = p[KP_] * e + inew + p[KD_] * dfilt + ff
            if umax > 0.0 and abs(u) > umax:
                if e * u > 0.0:          # conditional integration (anti-windup)
                    inew = integ
                u = p[KP_] * e + inew + p[KD_] * dfilt + ff
                u = max(-umax, min(umax, u))
            integ = inew
        else:
            vm = (y - yprev) / Tc
            yprev = y
            vhat += (vm - vhat) * Tc / (p[TF_] + Tc)
            vc = p[KPP_] * e + p[VFF_] * vr[k]
            ev = vc - vhat
            inew = integ + p[KIV_] * ev * Tc
            u = p[KVV_] * ev + inew + ff
            if umax > 0.0 and abs(u) > umax:
                if ev * u > 0.0:
                    inew = integ
                u = p[KVV_] * ev + inew + ff
                u = max(-umax, min(umax, u))
            integ = inew
        U[k] = u
        X[k] = x
        V[k] = v
        X2[k] = x2
        FR[k] = ffric
        # ---------------- plant, substeps of the zero-order hold ----------------
        for s in range(nsub):
            ts = t + s * dt
            if delay > 0.0:
                idx = int(math.floor((ts - delay) / Tc + 1e-9))
                ua = U[idx] if idx >= 0 else 0.0
            else:
                ua = u
            # friction level modulations
            fc_mod = 1.0 + _pf_profile(x, pfk, p[PFA_], p[PFP_], p[PFPH_], p[XLO_], p[XHI_])
            fv_mod = 1.0
            if drk == 1:
                h = p[DRD_] * math.exp(-ts / p[DRT_])
                fc_mod *= 1.0 + h
                fv_mod *= 1.0 + h
            elif drk == 2:
                h = p[DRD_] * ts / p[DRT_]
                fc_mod *= 1.0 + h
                fv_mod *= 1.0 + h
            if htk != 0.0:
                hh = htk * hm / vmax
                fc_mod *= 1.0 + hh
                fv_mod *= 1.0 + hh
            g = Fc * fc_mod + lf * abs(ua)
            if dFs != 0.0:
                g += dFs * fc_mod * _stribeck_shape(v, vs, ssh)
            gc = g * (1.0 - psh)
            fvisc = (Fv * v + dFv * abs(v)) * fv_mod
            fo = 0.0
            if pgk > 0:
                fo += _pg_force(x, pgk, p[PGA_], p[PGP_], p[PGPH_], p[PGX0_])
            fo += off
            if rpa != 0.0:
                fo += rpa * math.sin(2.0 * math.pi * p[RPF_] * ts + p[RPPH_])
            if drag != 0.0:
                fo += drag * v * abs(v)
            fload = 0.0
            if m2 > 0.0:
                d = x - x2
                dv = v - v2
                if gap <= 0.0:
                    fload = k2 * d + c2 * dv
                else:
                    if d > gap:
                        fload = k2 * (d - gap) + c2 * dv
                        if fload < 0.0:
                            fload = 0.0
                    elif d < -gap:
                        fload = k2 * (d + gap) + c2 * dv
                        if fload > 0.0:
                            fload = 0.0
            fext = ua - fvisc - fo - fload
            # backward Euler on the stiff linear part: elastic Maxwell-slip elements (springs k_i,
            # dampers c_i while they hold) and, for LuGre, the bristles with the relaxation rate
            # sigma0 |v| / g frozen over the step; the Coulomb/stick contact is set-valued and
            # projected (Moreau) on the same effective impedance.
            Fel = 0.0
            Ku = 0.0
            Cu = 0.0
            for i in range(ne):
                Fel += elk[i] * zel[i]
                if abs(zel[i]) < eld[i]:
                    Ku += elk[i]
                    Cu += elc[i]
            meff = M1 / dt + dt * Ku + Cu
            rhs = M1 * v / dt + fext - Fel
            if contact == 0:
                vstar = rhs / meff
                b = gc / meff
                if abs(vstar) <= b:
                    vn = 0.0
                elif vstar > 0.0:
                    vn = vstar - b
                else:
                    vn = vstar + b
                fcon = (vstar - vn) * meff
            else:
                gl = max(gc, 1e-12)
                den = 1.0 + dt * s0 * abs(v) / gl
                A = z / den
                B = dt / den
                meff2 = meff + s0 * B + s1 * B / dt
                vn = (rhs - s0 * A - s1 * (A - z) / dt) / meff2
                zn = A + B * vn
                fcon = s0 * zn + s1 * (zn - z) / dt
                z = zn
            ffric = fcon + fvisc + Fel + dt * Ku * vn + Cu * vn
            for i in range(ne):
                zel[i] += vn * dt
                if zel[i] > eld[i]:
                    zel[i] = eld[i]
                elif zel[i] < -eld[i]:
                    zel[i] = -eld[i]
            if m2 > 0.0:
                v2 += dt * fload / m2
                x2 += dt * v2
            if htk != 0.0:
                hm += dt * (abs(vn) - hm) / httau
            v = vn
            x += dt * vn
    return X, V, U, FR, X2


# --------------------------------------------------------------------------------------------
# trajectories
# --------------------------------------------------------------------------------------------
def _raised_cos_move(D, vpk, amax, dt):
    """velocity samples of a jerk-limited (raised-cosine acceleration) move of signed length D"""
    s = np.sign(D)
    D = abs(D)
    vpk = min(vpk, math.sqrt(2.0 * amax * D / math.pi))
    Ta = math.pi * vpk / (2.0 * amax)
    Tcst = max(D / vpk - Ta, 0.0)
    na = max(int(round(Ta / dt)), 2)
    nc = int(round(Tcst / dt))
    ramp = 0.5 * vpk * (1.0 - np.cos(np.pi * np.arange(na) / na))
    vel = np.concatenate([ramp, np.full(nc, vpk), ramp[::-1]])
    # exact length
    vel *= D / (vel.sum() * dt)
    return s * vel


def traj_ptp(rng, dur, dt, center, L, vmax, amax, dwell=(0.2, 1.2), back_forth=False):
    """S-curve point-to-point moves with dwells (back_forth: triangle-like constant-speed strokes
    between two ends, no dwell, speeds varying stroke to stroke)"""
    n = int(round(dur / dt))
    vel = [np.zeros(int(rng.uniform(0.3, 0.6) / dt))]
    pos = center + rng.uniform(-0.1, 0.1) * L
    x0 = pos
    lo, hi = center - 0.47 * L, center + 0.47 * L
    total = len(vel[0])
    if back_forth:
        a_end = center - rng.uniform(0.3, 0.47) * L
        b_end = center + rng.uniform(0.3, 0.47) * L
        levels = rng.permutation(np.linspace(0.15, 1.0, 6)) * vmax
        j = 0
    while total < n:
        if back_forth:
            tgt = b_end if pos < 0.5 * (a_end + b_end) else a_end
            vpk = levels[j % len(levels)]
            j += 1
            dw = rng.uniform(0.0, 0.05)
        else:
            for _ in range(50):
                tgt = rng.uniform(lo, hi)
                if abs(tgt - pos) > 0.08 * L:
                    break
            vpk = rng.uniform(0.25, 1.0) * vmax
            dw = rng.uniform(*dwell)
        mv = _raised_cos_move(tgt - pos, vpk, amax, dt)
        pos += mv.sum() * dt
        vel.append(mv)
        nd = int(dw / dt)
        vel.append(np.zeros(nd))
        total += len(mv) + nd
    v = np.concatenate(vel)[:n]
    if len(v) < n:
        v = np.concatenate([v, np.zeros(n - len(v))])
    # finish at rest: taper the last 0.3 s with a stop is not guaranteed; leave as is
    return x0, v


def _scale_smooth(rng, raw, dt, center, L, vmax, amax):
    """scale a smooth zero-mean signal into travel, top speed, acceleration limits"""
    v = np.gradient(raw, dt)
    a = np.gradient(v, dt)
    s = min(0.45 * L / np.max(np.abs(raw)), rng.uniform(0.7, 1.0) * vmax / np.max(np.abs(v)),
            1.2 * amax / np.max(np.abs(a)))
    x = center + s * raw
    return x


def _band(dur, L, vmax, amax):
    """frequency band where travel, speed and acceleration limits all matter about equally:
    above f_t a sine at top speed fits the travel, below f_a it stays within amax"""
    f_t = vmax / (2 * np.pi * 0.45 * L)
    f_a = amax / (2 * np.pi * vmax)
    lo = max(0.6 * f_t, 2.0 / dur, 0.08)
    hi = max(1.5 * max(f_t, f_a), 2 * lo)
    return lo, min(hi, 6.0)


def _window(n, dt, t_in=1.0):
    w = np.ones(n)
    m = min(int(t_in / dt), n // 4)
    ramp = 0.5 * (1 - np.cos(np.pi * np.arange(m) / m))
    w[:m] = ramp
    w[n - m:] = ramp[::-1]
    return w


def traj_multisine(rng, dur, dt, center, L, vmax, amax):
    n = int(round(dur / dt))
    t = np.arange(n) * dt
    nf = rng.integers(3, 7)
    flo, fhi = _band(dur, L, vmax, amax)
    f = np.sort(np.exp(rng.uniform(np.log(flo), np.log(fhi), nf)))
    A = f ** -rng.uniform(0.5, 1.2)
    ph = rng.uniform(0, 2 * np.pi, nf)
    raw = (A[None, :] * np.sin(2 * np.pi * f[None, :] * t[:, None] + ph[None, :])).sum(1)
    pre = int(rng.uniform(0.3, 0.6) / dt)
    w = _window(n - pre, dt)
    raw = np.concatenate([np.zeros(pre), (raw[:n - pre] - raw[:n - pre].mean()) * w])
    x = _scale_smooth(rng, raw, dt, center, L, vmax, amax)
    return x


def traj_random(rng, dur, dt, center, L, vmax, amax):
    n = int(round(dur / dt))
    hc = 0.01
    nc = int(dur / hc) + 10
    flo, fhi = _band(dur, L, vmax, amax)
    fc = _lu(rng, max(flo, 0.15), max(fhi, 0.3))
    sos = signal.butter(4, fc, fs=1 / hc, output="sos")
    w = signal.sosfiltfilt(sos, rng.standard_normal(nc + 400))[200:200 + nc]
    tc = np.arange(nc) * hc
    t = np.arange(n) * dt
    raw = np.interp(t, tc, w)
    # interp is piecewise linear: smooth again on the fine grid
    sos2 = signal.butter(2, min(8.0, 0.2 / dt), fs=1 / dt, output="sos")
    raw = signal.sosfiltfilt(sos2, raw)
    pre = int(rng.uniform(0.3, 0.6) / dt)
    wdw = _window(n - pre, dt)
    raw = np.concatenate([np.zeros(pre), (raw[:n - pre] - raw[:n - pre].mean()) * wdw])
    return _scale_smooth(rng, raw, dt, center, L, vmax, amax)


TRAJ_KINDS = ["ptp", "multisine", "triangle", "random"]


def make_reference(kind, rng, dur, dt, center, L, vmax, amax):
    if kind in ("ptp", "triangle"):
        x0, v = traj_ptp(rng, dur, dt, center, L, vmax, amax, back_forth=(kind == "triangle"))
        r = x0 + np.concatenate([[0.0], np.cumsum(v[:-1]) * dt])
        vr = v
        ar = np.gradient(v, dt)
    elif kind == "multisine":
        r = traj_multisine(rng, dur, dt, center, L, vmax, amax)
        vr = np.gradient(r, dt)
        ar = np.gradient(vr, dt)
    else:
        r = traj_random(rng, dur, dt, center, L, vmax, amax)
        vr = np.gradient(r, dt)
        ar = np.gradient(vr, dt)
    return r, vr, ar


# --------------------------------------------------------------------------------------------
# rig drawing
# --------------------------------------------------------------------------------------------
def _lu(rng, a, b):
    return float(math.exp(rng.uniform(math.log(a), math.log(b))))


def _grade(s, weak, strong, log=True):
    """strength s in [0, 1] -> value between weak and strong"""
    if log:
        return float(math.exp(math.log(weak) + s * (math.log(strong) - math.log(weak))))
    return float(weak + s * (strong - weak))


def draw_rig(rng, spec):
    """spec: dict(effects=[...], outside=None|kind, strength={eff: s}, rotary=None|bool,
    jitter=bool, baseline='reference'|'rigid').  Returns a rig dict (JSON-able)."""
    effects = list(spec.get("effects", []))
    outside = spec.get("outside")
    S = spec.get("strength", {})
    jitter = bool(spec.get("jitter", False))
    rotary = spec.get("rotary")
    if rotary is None:
        rotary = bool(rng.random() < 0.4)
    if jitter:
        rotary = True
    if "position_dependent_force" in effects and spec.get("pg_kind") == "gravity":
        rotary = True
    rig = dict(rotary=rotary, effects=effects, outside=outside, jitter=jitter)
    # the ranges of the brief, drawn jointly so that the inertial force at full acceleration
    # stays within 0.2 - 25 x the Coulomb level (a servo whose friction is 0.1 % of its force,
    # or whose inertia never shows, is not an axis anyone identifies friction on)
    Mlo, Mhi, Flo, Fhi, vlo, vhi = (0.0005, 0.5, 0.02, 5.0, 2.0, 40.0) if rotary else (2.0, 150.0, 2.0, 60.0, 0.05, 0.5)
    for _ in range(200):
        Fc = _lu(rng, Flo, Fhi)
        vmax = _lu(rng, vlo, vhi)
        t_acc = rng.uniform(0.06, 0.3)
        amax = vmax / t_acc
        lo, hi = max(Mlo, 0.2 * Fc / amax), min(Mhi, 25.0 * Fc / amax)
        if lo < hi:
            M = _lu(rng, lo, hi)
            break
    if rotary:
        L = _lu(rng, 3.0, 40.0)
        counts = 2 ** int(rng.integers(15, 21))
        res = 2 * math.pi / counts
    else:
        L = _lu(rng, 0.05, 0.8)
        res = _lu(rng, 0.1e-6, 2e-6)
    # keep the travel reachable at speed within a few seconds
    L = min(L, vmax * 2.5)
    if L < 12 * vmax * 0.05:
        L = 12 * vmax * 0.05
    Fv = rng.uniform(0.2, 2.0) * Fc / vmax
    center = 0.0 if rotary else rng.uniform(-0.3, 0.3) * L
    if rotary and "position_dependent_force" in effects:
        center = rng.uniform(-1.0, 1.0)
    rig.update(M=M, Fc=Fc, Fv=Fv, vmax=vmax, L=L, amax=amax, center=center)
    contact = "lugre" if rng.random() < 0.5 else "stick"
    rig["contact"] = contact
    P = dict(Fc=Fc, Fv=Fv, vmax=vmax, x_lo=center - 0.5 * L, x_hi=center + 0.5 * L)
    P["contact"] = 1 if contact == "lugre" else 0
    law = {}   # the planted laws (truth.py reads these)

    # ---------------- planted effects ----------------
    for eff in effects + ([outside] if outside else []):
        s = float(S.get(eff, rng.uniform(0, 1)))
        if eff == "asymmetric_friction":
            d = _grade(s, 0.06, 0.6) * Fv * (1 if rng.random() < 0.5 else -1)
            P["dFv"] = d
            law[eff] = dict(dFv=d)
        elif eff == "stribeck":
            dFs = _grade(s, 0.12, 1.0) * Fc
            vs = vmax * rng.uniform(0.04, 0.2)
            shape = 1 if rng.random() < 0.5 else 2
            P.update(dFs=dFs, vs=vs, sshape=shape)
            law[eff] = dict(dFs=dFs, vs=vs, shape=["", "exp15", "lorentz"][shape])
        elif eff == "presliding_hysteresis":
            share = _grade(s, 0.2, 0.8, log=False)
            ne = int(rng.integers(3, 6))
            dmax = _grade(s, 8.0, 60.0) * rng.uniform(0.8, 1.25)
            D = np.geomspace(5.0, max(dmax, 6.0), ne)          # in encoder steps (res drawn later)
            w = rng.dirichlet(np.ones(ne) * 2.0) * share * Fc
            law[eff] = dict(share=share, D_steps=D.tolist(), w=w.tolist())
            P["pshare"] = share
        elif eff == "position_dependent_friction":
            a = _grade(s, 0.08, 0.5)
            kind = int(rng.choice([1, 1, 2, 3]))
            per = L / rng.uniform(1.0, 4.0)
            phi = rng.uniform(0, 2 * np.pi)
            if kind != 1:
                a *= 1 if rng.random() < 0.5 else -1
            P.update(pf_kind=kind, pf_a=a, pf_p=per, pf_phi=phi)
            law[eff] = dict(kind=["", "sine", "linear", "quadratic"][kind], a=a, per=per, phi=phi)
        elif eff == "position_dependent_force":
            want = spec.get("pg_kind")
            if want is None:
                opts = ["cogging", "spring", "cable"] + (["gravity", "gravity"] if rotary else [])
                want = str(rng.choice(opts))
            kind = {"cogging": 1, "spring": 2, "gravity": 3, "cable": 4}[want]
            a = _grade(s, 0.1, 1.0) * Fc
            if kind == 3:
                a = _grade(s, 0.3, 3.0) * Fc
            per = {1: L / rng.uniform(3.0, 15.0), 2: 0.5 * L, 3: 1.0, 4: 0.3 * L}[kind]
            phi = rng.uniform(0, 2 * np.pi)
            x0 = center + rng.uniform(-0.3, 0.3) * L
            P.update(pg_kind=kind, pg_a=a, pg_p=per, pg_phi=phi, pg_x0=x0)
            law[eff] = dict(kind=want, a=a, per=per, phi=phi, x0=x0)
        elif eff == "input_delay":
            tau = _grade(s, 1e-3, 8e-3)
            P["delay"] = tau
            law[eff] = dict(tau=tau)
        elif eff == "friction_drift":
            d = _grade(s, 0.1, 0.6)
            kind = 1 if rng.random() < 0.6 else 2
            if kind == 1:
                T = rng.uniform(1.5, 8.0)
            else:
                T = rng.uniform(8.0, 25.0)
                d *= 1 if rng.random() < 0.5 else -0.7
            P.update(dr_kind=kind, dr_d=d, dr_T=T)
            law[eff] = dict(kind=["", "exp", "linear"][kind], d=d, T=T)
        elif eff == "heating":
            k = _grade(s, 0.15, 0.9) * (1 if rng.random() < 0.5 else -0.6)
            tau = rng.uniform(1.5, 5.0)
            P.update(ht_k=k, ht_tau=tau)
            law[eff] = dict(k=k, tau=tau)
        elif eff == "compliance":
            frac = _grade(s, 0.08, 0.45)
            fn = _lu(rng, 3.0, 30.0)
            zeta = rng.uniform(0.03, 0.15)
            m2 = frac * M
            wn = 2 * math.pi * fn
            P.update(m2=m2, k2=m2 * wn ** 2, c2=2 * zeta * wn * m2)
            law[eff] = dict(m2=m2, fn=fn, zeta=zeta)
        elif eff == "offset":
            F0 = _grade(s, 0.06, 0.5) * Fc * (1 if rng.random() < 0.5 else -1)
            P["offset"] = F0
            law[eff] = dict(F0=F0)
        # ---- outside the catalogue ----
        elif eff == "drag":
            c = _grade(s, 0.2, 1.0) * Fc / vmax ** 2
            P["drag"] = c
            law[eff] = dict(c=c)
        elif eff == "ripple":
            a = _grade(s, 0.1, 0.5) * Fc
            f = rng.uniform(2.0, 15.0)
            P.update(rp_a=a, rp_f=f, rp_phi=rng.uniform(0, 2 * np.pi))
            law[eff] = dict(a=a, f=f)
        elif eff == "backlash":
            frac = _grade(s, 0.15, 0.5)
            m2 = frac * M
            wn = 2 * math.pi * rng.uniform(30.0, 60.0)
            gap = rng.uniform(10, 60)                           # encoder steps
            P.update(m2=m2, k2=m2 * wn ** 2, c2=2 * 0.15 * wn * m2)
            law[eff] = dict(m2=m2, gap_steps=gap, fn=wn / 2 / math.pi)
        elif eff == "load_friction":
            mu = _grade(s, 0.05, 0.25)
            P["loadfric"] = mu
            law[eff] = dict(mu=mu)
        else:
            raise ValueError(eff)
    M1 = M - P.get("m2", 0.0)
    P["M1"] = M1
    # ---------------- controller ----------------
    fctrl = int(rng.choice([1000, 2000, 4000, 5000, 8000, 10000]))
    if jitter:
        fctrl = int(rng.choice([1000, 2000, 4000]))
    Tc = 1.0 / fctrl
    kind = str(rng.choice(["pid", "cascade", "pid_ff", "cascade_ff"]))
    wc = 2 * math.pi * _lu(rng, 6.0, 30.0)
    wc = min(wc, 2 * math.pi * fctrl / 60.0)
    tau = P.get("delay", 0.0)
    if tau > 0:
        wc = min(wc, 0.25 / tau)
    if "compliance" in law:
        wc = min(wc, 2 * math.pi * law["compliance"]["fn"] * 1.5)
    # encoder: drawn resolution, refined when the loop's derivative/velocity path would turn one
    # count into a command chatter above rho Fc (a drive that loud is not a tuned servo)
    rho = rng.uniform(0.1, 0.4)
    n_tf = rng.uniform(5.0, 12.0)
    kiv_div = rng.uniform(4.0, 8.0)
    kpp_div = rng.uniform(3.0, 5.0)
    ki_fac = rng.uniform(0.3, 1.0)
    res_floor = 2 * math.pi / 2 ** 26 if rotary else 2e-9
    for _ in range(40):
        if kind.startswith("pid"):
            kd_eff, tf = 3 * M * wc, 1.0 / (wc * n_tf)
        else:
            kd_eff, tf = M * 2.5 * wc, 1.0 / (2.5 * wc * n_tf)
        res_max = rho * Fc * tf / kd_eff
        if res_max >= res_floor:
            break
        wc *= 0.85
    if res > res_max:
        if rotary:
            res = 2 * math.pi / 2 ** int(math.ceil(math.log2(2 * math.pi / res_max)))
        else:
            res = res_max
    res = max(res, res_floor)
    rig["res"] = res
    P["res"] = res
    ctrl = dict(kind=kind, rate=fctrl, wc=wc, chatter_rho=rho)
    if kind.startswith("pid"):
        P.update(ctrl=0, kp=3 * M * wc ** 2, ki=M * wc ** 3 * ki_fac, kd=3 * M * wc, tf=1.0 / (wc * n_tf))
    else:
        wv = 2.5 * wc
        P.update(ctrl=1, kvv=M * wv, kiv=M * wv * wv / kiv_div, kpp=wv / kpp_div, tf=1.0 / (wv * n_tf))
    if kind.endswith("_ff"):
        err = rng.uniform(-0.2, 0.2)
        P.update(mff=M * (1 + err), fvff=Fv * rng.uniform(0.7, 1.3),
                 fcff=(Fc * rng.uniform(0.5, 1.1) if rng.random() < 0.5 else 0.0), vff=1.0)
        ctrl.update(mass_error=err)
    elif kind.startswith("cascade"):
        P["vff"] = 1.0 if rng.random() < 0.5 else 0.0
    sat = bool(rng.random() < 0.3)
    ctrl["saturation"] = sat
    rig["ctrl"] = ctrl
    # ---------------- contact stiffness, elements (need the resolution) ----------------
    gmax = Fc + P.get("dFs", 0.0)
    w0 = 0.0
    if contact == "lugre":
        # LuGre bristles: range g / sigma0 below half an encoder step
        s0 = gmax / (rng.uniform(0.1, 0.4) * res)
        w0 = math.sqrt(s0 / M1)
        P["sigma0"] = s0
        P["sigma1"] = 2 * rng.uniform(0.3, 1.0) * math.sqrt(s0 * M1)
    if "presliding_hysteresis" in law:
        ph = law["presliding_hysteresis"]
        Dv = np.array(ph.pop("D_steps")) * res
        ph["D"] = Dv.tolist()
        wv_ = np.array(ph["w"])
        kv = wv_ / Dv
        w0 = max(w0, math.sqrt(kv.sum() / M1))
        cv = 2 * 0.3 * np.sqrt(kv * M1 / len(kv))
        rig["elements"] = dict(k=kv.tolist(), D=Dv.tolist(), c=cv.tolist())
    if "backlash" in law:
        law["backlash"]["gap"] = law["backlash"].pop("gap_steps") * res
        P["gap"] = law["backlash"]["gap"]
    # substeps: stiff parts stable, at least 1
    wl = math.sqrt(P["k2"] / P["m2"]) if P.get("m2", 0.0) > 0 else 0.0
    wmax = max(wl, wc * 5)          # the contact and the elements are implicit
    dt_max = min(Tc, 0.08 / wmax, 1e-4)
    nsub = int(math.ceil(Tc / dt_max))
    P.update(Tc=Tc, nsub=nsub)
    rig["nsub"] = nsub
    # drive limit: about the force the nominal motion needs
    need = M * amax + Fc + P.get("dFs", 0.0) + Fv * vmax + abs(P.get("pg_a", 0.0)) + abs(P.get("offset", 0.0))
    if sat:
        P["umax"] = need * rng.uniform(0.8, 1.2)
        ctrl["umax"] = P["umax"]
    rig["P"] = P
    rig["law"] = law
    # ---------------- logger ----------------
    if jitter:
        flog = float(rng.uniform(100.0, 200.0))
    else:
        opts = [f for f in (200, 250, 500, 1000, 2000, 2500, 5000) if f <= fctrl]
        flog = float(rng.choice(opts))
    noise = rng.uniform(0.003, 0.015) * Fc
    rig["log"] = dict(rate=flog, noise=noise)
    return rig


def simulate(rig, traj_kind, dur, seed):
    """simulate one run; returns dict with control-grid arrays and the reference"""
    rng = np.random.default_rng(seed)
    P = rig["P"]
    Tc = P["Tc"]
    r, vr, ar = make_reference(traj_kind, rng, dur, Tc, rig["center"], rig["L"], rig["vmax"], rig["amax"])
    p = pack(P)
    el = rig.get("elements")
    if el:
        elk, eld, elc = (np.array(el[k], float) for k in ("k", "D", "c"))
    else:
        elk = eld = elc = np.zeros(0)
    X, V, U, FR, X2 = _sim_kernel(p, r, vr, ar, elk, eld, elc, float(r[0]))
    return dict(t=np.arange(len(r)) * Tc, r=r, vr=vr, ar=ar, x=X, v=V, u=U, ffric=FR, x2=X2, Tc=Tc)


def log_run(rig, sim, seed):
    """sample the logger: quantised encoder position and commanded force (+ noise)"""
    rng = np.random.default_rng(seed + 7777)
    Tc = sim["Tc"]
    dur = sim["t"][-1]
    lg = rig["log"]
    h = 1.0 / lg["rate"]
    if rig["jitter"]:
        steps = h * (1.0 + rng.uniform(-0.4, 0.4, int(dur / h * 1.5) + 10))
        tl = np.concatenate([[0.0], np.cumsum(steps)])
        tl = tl[tl < dur - 2 * Tc]
    else:
        tl = np.arange(0.0, dur - 2 * Tc, h)
    k = np.floor(tl / Tc + 1e-9).astype(int)
    k = np.minimum(k, len(sim["x"]) - 2)
    s = (tl - k * Tc) / Tc
    x0, x1 = sim["x"][k], sim["x"][k + 1]
    v0, v1 = sim["v"][k] * Tc, sim["v"][k + 1] * Tc
    # cubic Hermite between ticks
    h00 = 2 * s ** 3 - 3 * s ** 2 + 1
    h10 = s ** 3 - 2 * s ** 2 + s
    h01 = -2 * s ** 3 + 3 * s ** 2
    h11 = s ** 3 - s ** 2
    x = h00 * x0 + h10 * v0 + h01 * x1 + h11 * v1
    res = rig["P"]["res"]
    q = np.floor(x / res + 0.5) * res
    f = sim["u"][k] + rng.normal(0.0, lg["noise"], len(tl))
    return dict(t=tl, q=q, f=f, x=x)


# --------------------------------------------------------------------------------------------
# sanity checks
# --------------------------------------------------------------------------------------------
def sanity(rig, sim):
    """return (ok, info) for one simulated run"""
    x, r, u = sim["x"], sim["r"], sim["u"]
    info = {}
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(u))):
        return False, dict(reason="non-finite")
    err = r - x
    info["max_err_over_travel"] = float(np.max(np.abs(err)) / rig["L"])
    info["rms_err_over_travel"] = float(np.sqrt(np.mean(err ** 2)) / rig["L"])
    span = float(np.ptp(x))
    info["span_over_travel"] = span / rig["L"]
    info["peak_u_over_Fc"] = float(np.max(np.abs(u)) / rig["Fc"])
    ff = sim["ffric"]
    moving = np.abs(sim["v"]) > 0.2 * rig["vmax"]
    if moving.any():
        info["friction_moving_over_Fc"] = float(np.median(np.abs(ff[moving])) / rig["Fc"])
    # standstill: reference at rest for a while -> encoder should be quiet
    still = np.abs(sim["vr"]) < 1e-12
    if still.sum() > 100:
        dq = np.abs(np.diff(np.floor(x / rig["res"] + 0.5)))[still[1:]]
        info["dwell_frac_encoder_moving"] = float(np.mean(dq > 0))
        info["dwell_frac_v0"] = float(np.mean(sim["v"][still] == 0.0))
    ok = info["max_err_over_travel"] < 0.08 and info["rms_err_over_travel"] < 0.02 and \
        info["span_over_travel"] > 0.05 and info["span_over_travel"] < 1.3
    info["ok"] = bool(ok)
    return ok, info
