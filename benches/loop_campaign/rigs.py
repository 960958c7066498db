"""Simulated servo axes and planted EMPS runs for the campaign, built from the physics.

Nothing here is derived from ``gmsfric.loop`` (its rigs or its regression columns).  Two
simulators produce closed-loop runs:

* ``own``: a fixed-step integrator written here (numba when installed, plain Python otherwise),
  fine step = controller period / ``nsub``.  Mechanics: motor mass (or inertia) with a Karnopp
  stick-slip contact (set-valued stiction, Coulomb and viscous asymmetry, Stribeck hump of
  exponential or Lorentzian shape) or a Maxwell-slip contact (pre-sliding), position-dependent
  friction and force, friction drift in time, velocity-squared drag, an input delay (ring buffer,
  fractional), a load on a spring-damper behind the motor (optionally with backlash), external
  forces in time (ripple, square wave, constant).  Controllers: PID with filtered derivative and
  conditional-integration anti-windup, or a P-PI cascade with a filtered difference velocity;
  acceleration / velocity / Coulomb feedforward; drive saturation; encoder quantisation.
* ``core``: :func:`gmsfric.simulate_closed_loop` with a GMS, LuGre, Maxwell-slip or static
  (set-valued stiction) contact in the loop, PID or the EMPS P-P cascade, native input delay.

Logs: the position the encoder reads and the *commanded* force (what a drive logs), plus white
force noise, sampled at the log rate, optionally with irregular (jittered) time stamps.

Everything is in SI (m or rad, N or N m, s); units only change when files are written.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import io as sio
from scipy import interpolate, signal

import gmsfric as g

try:  # numba makes the campaign's own integrator ~100x faster; the code runs without it
    from numba import njit
except ImportError:  # pragma: no cover - exercised only without numba
    def njit(*args: Any, **kwargs: Any) -> Any:  # type: ignore[no-redef]
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

Array = NDArray[np.float64]

# ------------------------------------------------------------------------------------------
# Shapes shared by the simulator and the ground truth (the exact functional forms).

#: Length of a position-shape coefficient vector, see :func:`position_shape`.
SHAPE_LEN = 22


def position_shape(q: Any, c: Array) -> Any:
    """``g(q)`` (force units): line + up to 3 sines + 2 Gaussian bumps + ``sin(q + phi)`` + tanh.

    ``c`` = [k, q0, (A, period, phase) x3, (B, centre, width) x2, G, phi, T, q_t, w_t].
    """
    out = c[0] * (q - c[1])
    for i in range(3):
        a = c[2 + 3 * i]
        if a != 0.0:
            out = out + a * np.sin(2.0 * np.pi * q / c[3 + 3 * i] + c[4 + 3 * i])
    for i in range(2):
        b = c[11 + 3 * i]
        if b != 0.0:
            d = (q - c[12 + 3 * i]) / c[13 + 3 * i]
            out = out + b * np.exp(-0.5 * d * d)
    if c[17] != 0.0:
        out = out + c[17] * np.sin(q + c[18])
    if c[19] != 0.0:
        out = out + c[19] * np.tanh((q - c[20]) / c[21])
    return out


def stribeck_shape(x: Any, kind: float, delta: float) -> Any:
    """Hump of ``x = |v|/vs``: ``exp(-x^delta)`` (kind 0) or Lorentzian ``1/(1+x^2)`` (kind 1)."""
    if kind == 1:
        return 1.0 / (1.0 + x * x)
    return np.exp(-(x**delta))


def drift_shape(t: Any, kind: float, T: float) -> Any:
    """Friction change over a run: warm-up ``exp(-t/T)`` (kind 0) or linear ``t/T`` (kind 1)."""
    if kind == 1:
        return t / T
    return np.exp(-t / T)


_shape_nb = njit(cache=True)(position_shape)
_stribeck_nb = njit(cache=True)(stribeck_shape)
_drift_nb = njit(cache=True)(drift_shape)


def make_shape(**parts: Any) -> list[float]:
    """Coefficient vector for :func:`position_shape` from named parts.

    ``lin=(k, q0)``, ``sines=[(A, period, phase), ...]``, ``bumps=[(B, centre, width), ...]``,
    ``grav=(G, phi)``, ``tanh=(T, q0, w)``.
    """
    c = [0.0] * SHAPE_LEN
    if "lin" in parts:
        c[0], c[1] = parts["lin"]
    for i, s in enumerate(parts.get("sines", [])):
        c[2 + 3 * i : 5 + 3 * i] = s
    for i, b in enumerate(parts.get("bumps", [])):
        c[11 + 3 * i : 14 + 3 * i] = b
    if "grav" in parts:
        c[17], c[18] = parts["grav"]
    if "tanh" in parts:
        c[19], c[20], c[21] = parts["tanh"]
    return [float(x) for x in c]


# ------------------------------------------------------------------------------------------
# The campaign's own integrator.

# Mechanics parameter vector P (indices are compile-time constants for numba).
I_M, I_FV_POS, I_FV_NEG, I_FC_POS, I_FC_NEG = 0, 1, 2, 3, 4
I_ST_DF, I_ST_VS, I_ST_KIND, I_ST_DELTA, I_CONTACT = 5, 6, 7, 8, 9
I_DRAG2, I_DRIFT_DF, I_DRIFT_DFV, I_DRIFT_T, I_DRIFT_KIND = 10, 11, 12, 13, 14
I_M2, I_K2, I_C2, I_GAP, I_B2, I_DELAY, I_F0 = 15, 16, 17, 18, 19, 20, 21
I_RIP_A, I_RIP_F, I_RIP_PH, I_SQ_A, I_SQ_F, I_SQ_PH = 22, 23, 24, 25, 26, 27
I_POSF_ON, I_POSFRIC_ON = 28, 29
P_LEN = 30

# Controller vector C.
C_KIND, C_KP, C_KI, C_KD, C_TF, C_KPP, C_KV, C_TIV, C_VF_TAU = 0, 1, 2, 3, 4, 5, 6, 7, 8
C_FF_A, C_FF_V, C_FF_C, C_FF_VEPS, C_FF_VEL, C_ULIM, C_QUANT = 9, 10, 11, 12, 13, 14, 15
C_LEN = 16


@njit(cache=True)
def _integrate(r: Array, rv: Array, ra: Array, nsub: int, Tc: float, C: Array, P: Array,
               posf: Array, posfric: Array, ms_k: Array, ms_w: Array) -> tuple[Array, Array, Array]:
    n = r.size
    h = Tc / nsub
    N = n * nsub
    xs = np.empty(N)
    vs = np.empty(N)
    us = np.empty(N)
    M = P[I_M]
    x1 = r[0]
    v1 = 0.0
    x2 = r[0]
    v2 = 0.0
    nel = ms_k.size
    z = np.zeros(nel)
    fcm = 0.5 * (P[I_FC_POS] + P[I_FC_NEG])
    wsum = 0.0
    for e in range(nel):
        wsum += ms_w[e]
    dsteps = P[I_DELAY] / h
    quant = C[C_QUANT]
    ulim = C[C_ULIM]
    integ = 0.0
    dfilt = 0.0
    e_prev = 0.0
    y_prev = 0.0
    vf = 0.0
    two_pi = 2.0 * np.pi
    for k in range(n):
        y = x1
        if quant > 0.0:
            y = np.round(x1 / quant) * quant
        ff = C[C_FF_A] * ra[k] + C[C_FF_V] * rv[k] + C[C_FF_C] * np.tanh(rv[k] / C[C_FF_VEPS])
        if C[C_KIND] == 0.0:
            e = r[k] - y
            if k == 0:
                e_prev = e
            dfilt += Tc / (C[C_TF] + Tc) * ((e - e_prev) / Tc - dfilt)
            e_prev = e
            u_un = C[C_KP] * e + C[C_KI] * integ + C[C_KD] * dfilt + ff
            if not (abs(u_un) > ulim and e * u_un > 0.0):
                integ += e * Tc
        else:
            if k == 0:
                y_prev = y
            vm = (y - y_prev) / Tc
            y_prev = y
            vf += Tc / (C[C_VF_TAU] + Tc) * (vm - vf)
            ev = C[C_KPP] * (r[k] - y) + C[C_FF_VEL] * rv[k] - vf
            u_un = C[C_KV] * (ev + integ / C[C_TIV]) + ff
            if not (abs(u_un) > ulim and ev * u_un > 0.0):
                integ += ev * Tc
        u = min(max(u_un, -ulim), ulim)
        for j in range(nsub):
            i = k * nsub + j
            us[i] = u
            xs[i] = x1
            vs[i] = v1
            pos = i - dsteps
            if pos <= 0.0:
                ua = us[0]
            else:
                i0 = int(pos)
                w = pos - i0
                i1 = i0 + 1 if i0 + 1 <= i else i
                ua = us[i0] * (1.0 - w) + us[i1] * w
            t = i * h
            fext = P[I_F0]
            if P[I_POSF_ON] != 0.0:
                fext += _shape_nb(x1, posf)
            if P[I_RIP_A] != 0.0:
                fext += P[I_RIP_A] * np.sin(two_pi * P[I_RIP_F] * t + P[I_RIP_PH])
            if P[I_SQ_A] != 0.0:
                fext += P[I_SQ_A] * (1.0 if np.sin(two_pi * P[I_SQ_F] * t + P[I_SQ_PH]) >= 0.0 else -1.0)
            dlevel = 0.0  # change of the Coulomb level (N)
            if P[I_POSFRIC_ON] != 0.0:
                dlevel += _shape_nb(x1, posfric)
            dshape = 0.0
            if P[I_DRIFT_DF] != 0.0 or P[I_DRIFT_DFV] != 0.0:
                dshape = _drift_nb(t, P[I_DRIFT_KIND], P[I_DRIFT_T])
                dlevel += P[I_DRIFT_DF] * dshape
            fv = P[I_FV_POS] if v1 > 0.0 else P[I_FV_NEG]
            visc = (fv + P[I_DRIFT_DFV] * dshape) * v1 + P[I_DRAG2] * v1 * abs(v1)
            fsp = 0.0
            if P[I_M2] > 0.0:
                d = x1 - x2
                dv = v1 - v2
                gap = 0.5 * P[I_GAP]
                if gap > 0.0:
                    if d > gap:
                        fsp = P[I_K2] * (d - gap) + P[I_C2] * dv
                    elif d < -gap:
                        fsp = P[I_K2] * (d + gap) + P[I_C2] * dv
                else:
                    fsp = P[I_K2] * d + P[I_C2] * dv
                v2 += h * (fsp - P[I_B2] * v2) / P[I_M2]
            fa = ua + fext - visc - fsp
            if P[I_CONTACT] == 0.0:
                # Karnopp: stick when the friction needed to stop within the step is below the
                # static level in the direction the axis would move.
                v_free = v1 + h * fa / M
                if v1 == 0.0 or v_free * v1 < 0.0:
                    push = M * v1 / h + fa
                    direction = 1.0 if push > 0.0 else -1.0
                    lvl = (P[I_FC_POS] if direction > 0.0 else P[I_FC_NEG]) + dlevel + P[I_ST_DF]
                    lvl = max(lvl, 0.0)
                    if abs(push) <= lvl:
                        v1n = 0.0
                    else:
                        v1n = v1 + h * (fa - direction * lvl) / M
                else:
                    sgn = 1.0 if v1 > 0.0 else -1.0
                    lvl = (P[I_FC_POS] if sgn > 0.0 else P[I_FC_NEG]) + dlevel
                    if P[I_ST_DF] != 0.0:
                        lvl += P[I_ST_DF] * _stribeck_nb(abs(v1) / P[I_ST_VS], P[I_ST_KIND], P[I_ST_DELTA])
                    lvl = max(lvl, 0.0)
                    v1n = v1 + h * (fa - sgn * lvl) / M
                    if v1n * v1 < 0.0:
                        v1n = 0.0
            else:
                fms = 0.0
                for e in range(nel):
                    fms += ms_k[e] * z[e]
                v1n = v1 + h * (fa - fms) / M
            dx = h * v1n
            x1 += dx
            v1 = v1n
            x2 += h * v2
            if nel > 0 and P[I_CONTACT] != 0.0:
                scale = max(1.0 + dlevel / wsum, 0.0)
                for e in range(nel):
                    lim = ms_w[e] * scale / ms_k[e]
                    ze = z[e] + dx
                    z[e] = min(max(ze, -lim), lim)
    return xs, vs, us


# ------------------------------------------------------------------------------------------
# Trajectories (reference position, velocity, acceleration at the controller rate).


def trajectory(spec: dict[str, Any], duration: float, fs: float) -> tuple[Array, Array, Array]:
    """Reference ``(r, rv, ra)`` at ``fs`` for a trajectory spec.

    ``spec``: ``kind`` in {trapezoid, sweep, random, mixed}, ``seed``, ``travel``, ``vmax``,
    ``amax`` (SI), optional ``dwell`` (s, min/max), ``f_lo``/``f_hi`` (sweep, Hz), ``f_band``
    (random, Hz).
    """
    n = int(round(duration * fs))
    rng = np.random.default_rng(spec["seed"])
    kind = spec["kind"]
    if kind == "trapezoid":
        return _trapezoid(spec, n, fs, rng)
    if kind == "sweep":
        return _sweep(spec, n, fs, rng)
    if kind == "random":
        return _random(spec, n, fs, rng)
    if kind == "mixed":
        n1 = n // 2
        r1, v1, a1 = _trapezoid(spec, n1, fs, rng)
        r2, v2, a2 = (_random if rng.random() < 0.5 else _sweep)(spec, n - n1, fs, rng)
        r2 = r2 - r2[0] + r1[-1]  # the second part starts from rest (windowed), where the first ended
        return np.concatenate([r1, r2]), np.concatenate([v1, v2]), np.concatenate([a1, a2])
    raise ValueError(f"unknown trajectory kind {kind!r}")


def _trapezoid(spec: dict[str, Any], n: int, fs: float, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    dt = 1.0 / fs
    L, vmax, amax = spec["travel"], spec["vmax"], spec["amax"]
    dw = spec.get("dwell", (0.05, 0.4))
    acc = np.zeros(n)
    cur = rng.uniform(-0.3, 0.3) * L
    start = cur
    i = int(rng.uniform(*dw) * fs)
    while i < n:
        target = rng.uniform(-0.5, 0.5) * L
        d = target - cur
        if abs(d) < 0.05 * L:
            continue
        v = rng.uniform(0.3, 1.0) * vmax
        a = rng.uniform(0.4, 1.0) * amax
        ta = v / a
        if abs(d) < v * ta:
            ta, tc = math.sqrt(abs(d) / a), 0.0
        else:
            tc = (abs(d) - v * ta) / v
        na, nc = max(1, int(round(ta * fs))), int(round(tc * fs))
        a_eff = abs(d) / (na * (na + nc) * dt * dt) * np.sign(d)
        seg = np.concatenate([np.full(na, a_eff), np.zeros(nc), np.full(na, -a_eff)])
        m = min(seg.size, n - i)
        acc[i : i + m] = seg[:m]
        i += seg.size + int(rng.uniform(*dw) * fs)
        cur = target
    # jerk limit: a box filter keeps the velocity's integral, so moves still end at rest
    nj = max(1, int(round(spec.get("jerk_time", 0.02) * fs)))
    acc = np.convolve(acc, np.ones(nj) / nj, mode="same")
    vel = np.cumsum(acc) * dt
    pos = start + np.cumsum(vel) * dt
    return pos, vel, acc


def _window(n: int, fs: float, ramp: float = 0.5) -> Array:
    m = min(n // 4, int(ramp * fs))
    w = np.ones(n)
    if m > 1:
        ramp_up = np.sin(0.5 * np.pi * np.arange(m) / m) ** 2
        w[:m] = ramp_up
        w[n - m :] = ramp_up[::-1]
    return w


def _derivatives(r: Array, fs: float) -> tuple[Array, Array, Array]:
    rv = np.gradient(r, 1.0 / fs)
    return r, rv, np.gradient(rv, 1.0 / fs)


def _sweep(spec: dict[str, Any], n: int, fs: float, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    L, vmax, amax = spec["travel"], spec["vmax"], spec["amax"]
    f0, f1 = spec.get("f_lo", rng.uniform(0.1, 0.3)), spec.get("f_hi", rng.uniform(2.0, 8.0))
    t = np.arange(n) / fs
    T = t[-1] if n > 1 else 1.0
    f = f0 * (f1 / f0) ** (t / T)
    phase = 2 * np.pi * f0 * T / math.log(f1 / f0) * ((f1 / f0) ** (t / T) - 1.0)
    w = 2 * np.pi * f
    amp = np.minimum.reduce([np.full(n, 0.45 * L), 0.8 * vmax / w, 0.8 * amax / w**2])
    centre = rng.uniform(-0.1, 0.1) * L
    r = (centre + amp * np.sin(phase)) * _window(n, fs, 0.5 / f0)
    return _derivatives(r, fs)


def _random(spec: dict[str, Any], n: int, fs: float, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    L, vmax, amax = spec["travel"], spec["vmax"], spec["amax"]
    # band: where a motion over ~60 % of the travel reaches the speed or acceleration limit
    f_lim = min(math.sqrt(amax / (0.3 * L)), vmax / (0.3 * L)) / (2 * np.pi)
    fb = spec.get("f_band", float(np.clip(rng.uniform(0.8, 2.0) * f_lim, 0.05, 3.0)))
    # filtered noise made at a low rate (long filter memory), dropped margins, then a spline
    fs_low = max(20.0 * fb, 20.0)
    margin = int(4.0 / fb * fs_low)
    n_low = int(n / fs * fs_low) + 4
    sos = signal.butter(4, fb / (fs_low / 2), output="sos")
    x_low = signal.sosfiltfilt(sos, rng.standard_normal(n_low + 2 * margin))[margin : margin + n_low]
    spl = interpolate.CubicSpline(np.arange(n_low) / fs_low, x_low - x_low.mean())
    x = spl(np.arange(n) / fs) * _window(n, fs, 1.0 / fb)
    _, v, a = _derivatives(x, fs)
    s = min(0.45 * L / np.max(np.abs(x)), vmax / np.max(np.abs(v)), amax / np.max(np.abs(a)))
    return _derivatives(s * x, fs)


# ------------------------------------------------------------------------------------------
# Runs.


@dataclass
class Run:
    """One logged run in SI: time stamps, encoder position, logged (commanded) force.

    ``hold`` is half the controller period: a held command acts on average that much after its
    time stamp (part of every rig's physics, not a planted effect).
    """

    t: Array
    q: Array
    f: Array
    hold: float
    meta: dict[str, Any] = field(default_factory=dict)


def fine_steps(rig: dict[str, Any], effects: list[dict[str, Any]]) -> int:
    """Fine steps per controller period: at least 10, and ``h w_max < 0.5`` for the stiffest mode
    (contact elements on the motor mass, the load spring) so the explicit update stays accurate."""
    k = float(np.sum(rig.get("contact", {}).get("k", [0.0]))) if rig.get("contact", {}).get("model") == "maxwell" else 0.0
    w2 = max([math.sqrt(e["k2"] / e["m2"]) * math.sqrt(1 + e["m2"] / rig["M"]) for e in effects if e["name"] in ("compliance", "backlash")] + [0.0])
    w = max(math.sqrt(k / rig["M"]), w2)
    return max(10, int(math.ceil(2.0 * w / rig["f_ctrl"])))


def controller_vector(ctrl: dict[str, Any], mass: float, f_ctrl: float, quant: float, ulim: float) -> Array:
    """Controller gains from a bandwidth spec (``kind`` pid / ppi, ``fb`` Hz, feedforward)."""
    C = np.zeros(C_LEN)
    wb = 2 * np.pi * ctrl["fb"]
    if ctrl["kind"] == "pid":
        # poles of M s^3 + kd s^2 + kp s + ki at -wb (triple)
        C[C_KIND] = 0.0
        C[C_KP], C[C_KD], C[C_KI] = 3 * mass * wb**2, 3 * mass * wb, mass * wb**3
        C[C_TF] = 1.0 / (10 * wb)
    else:
        # velocity loop at wv = 4 wb (PI, zero at wv/4), position P at wb
        wv = 4 * wb
        C[C_KIND] = 1.0
        C[C_KV], C[C_TIV], C[C_KPP] = mass * wv, 4.0 / wv, wb
        C[C_VF_TAU] = 1.0 / (5 * wv)
        C[C_FF_VEL] = 1.0 if ctrl.get("ff_vel", False) else 0.0
    ff = ctrl.get("ff", {})
    C[C_FF_A] = ff.get("mass", 0.0)
    C[C_FF_V] = ff.get("fv", 0.0)
    C[C_FF_C] = ff.get("fc", 0.0)
    C[C_FF_VEPS] = ff.get("veps", 1.0)
    C[C_ULIM] = ulim
    C[C_QUANT] = quant
    return C


def mechanics_vector(rig: dict[str, Any], effects: list[dict[str, Any]], rng: np.random.Generator) -> tuple[Array, Array, Array, Array, Array]:
    """``P, posf, posfric, ms_k, ms_w`` for the own integrator from a rig and its effects."""
    P = np.zeros(P_LEN)
    P[I_M] = rig["M"]
    P[I_FV_POS] = P[I_FV_NEG] = rig["Fv"]
    P[I_FC_POS] = P[I_FC_NEG] = rig["Fc"]
    P[I_ST_VS], P[I_ST_DELTA], P[I_DRIFT_T] = 1.0, 1.0, 1.0
    posf = np.zeros(SHAPE_LEN)
    posfric = np.zeros(SHAPE_LEN)
    contact = rig.get("contact", {"model": "karnopp"})
    ms_k = np.zeros(0)
    ms_w = np.zeros(0)
    if contact["model"] == "maxwell":
        P[I_CONTACT] = 1.0
        ms_k, ms_w = np.asarray(contact["k"], float), np.asarray(contact["w"], float)
    elif contact["model"] != "karnopp":
        raise ValueError(f"own integrator has no contact {contact['model']!r}")
    for e in effects:
        name = e["name"]
        if name == "asymmetric_friction":
            P[I_FV_POS] += e.get("dFv", 0.0)
            P[I_FV_NEG] -= e.get("dFv", 0.0)
            P[I_FC_POS] += e.get("dFc", 0.0)
            P[I_FC_NEG] -= e.get("dFc", 0.0)
        elif name == "stribeck":
            P[I_ST_DF], P[I_ST_VS], P[I_ST_KIND], P[I_ST_DELTA] = e["dF"], e["vs"], e["kind"], e["delta"]
        elif name == "presliding_hysteresis":
            pass  # the Maxwell-slip contact itself (rig["contact"])
        elif name == "position_dependent_friction":
            posfric += np.asarray(e["shape"])
            P[I_POSFRIC_ON] = 1.0
        elif name == "position_dependent_force":
            posf += np.asarray(e["shape"])
            P[I_POSF_ON] = 1.0
        elif name == "input_delay":
            P[I_DELAY] = e["tau"]
        elif name == "friction_drift":
            P[I_DRIFT_DF], P[I_DRIFT_DFV], P[I_DRIFT_T], P[I_DRIFT_KIND] = e["dF"], e.get("dFv", 0.0), e["T"], e["kind"]
        elif name in ("compliance", "backlash"):
            P[I_M2], P[I_K2], P[I_C2] = e["m2"], e["k2"], e["c2"]
            P[I_GAP], P[I_B2] = e.get("gap", 0.0), e.get("b2", 0.0)
        elif name == "offset":
            P[I_F0] += e["f0"]
        elif name == "drag":
            P[I_DRAG2] = e["c2"]
        elif name == "ripple":
            P[I_RIP_A], P[I_RIP_F], P[I_RIP_PH] = e["amp"], e["freq"], rng.uniform(0, 2 * np.pi)
        elif name == "square":
            P[I_SQ_A], P[I_SQ_F], P[I_SQ_PH] = e["amp"], e["freq"], rng.uniform(0, 2 * np.pi)
        else:
            raise ValueError(f"unknown effect {name!r}")
    return P, posf, posfric, ms_k, ms_w


def _sample_indices(n_fine: int, h: float, step: int, jitter: str | None, rng: np.random.Generator) -> NDArray[np.int64]:
    if jitter is None:
        return np.arange(0, n_fine, step)
    if jitter == "robot":
        # a logger that wakes every 10 ms but is sometimes late by 2-8 ms (then on time again)
        T = 0.01
        k = np.arange(int(n_fine * h / T) - 1)
        late = np.where(rng.random(k.size) < 0.15, rng.uniform(0.002, 0.008, k.size), rng.uniform(0.0, 0.0005, k.size))
        tk = k * T + late
    elif jitter == "mild":
        T = step * h
        k = np.arange(int(n_fine / step) - 1)
        tk = k * T + rng.uniform(0.0, 0.35 * T, k.size)
    else:
        raise ValueError(f"unknown jitter {jitter!r}")
    idx = np.unique(np.round(tk / h).astype(np.int64))
    return idx[idx < n_fine]


def _finish_log(t: Array, x: Array, u: Array, quant: float, noise_sd: float, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    q = np.round(x / quant) * quant if quant > 0 else x.copy()
    return t, q, u + noise_sd * rng.standard_normal(u.size)


def simulate_run(case: dict[str, Any], which: str) -> Run:
    """Simulate the estimation (``which='est'``) or validation run of a simulated case."""
    if case["sim"] == "emps":
        return emps_run(case, which)
    rig = case["rig"]
    seed = case["seed"] + (0 if which == "est" else 7919)
    rng = np.random.default_rng(seed)
    f_ctrl = rig["f_ctrl"]
    r, rv, ra = trajectory(case["traj"][which], case["duration"], f_ctrl)
    effects = case["effects"] + case["outside"]
    ulim = rig.get("ulim") or np.inf  # None: no drive limit
    if case["sim"] == "own":
        nsub = rig.get("nsub") or fine_steps(rig, effects)
        C = controller_vector(rig["ctrl"], rig["M"], f_ctrl, rig["quant"], ulim)
        P, posf, posfric, ms_k, ms_w = mechanics_vector(rig, effects, rng)
        xs, vs, us = _integrate(r, rv, ra, nsub, 1.0 / f_ctrl, C, P, posf, posfric, ms_k, ms_w)
        h = 1.0 / f_ctrl / nsub
    elif case["sim"] == "core":
        xs, vs, us = _simulate_core(rig, effects, r, rv, ra, f_ctrl, ulim, rng)
        nsub, h = 1, 1.0 / f_ctrl
    else:
        raise ValueError(f"unknown simulator {case['sim']!r}")
    if not np.all(np.isfinite(xs)) or np.max(np.abs(xs - np.repeat(r, nsub))) > 0.5 * case["traj"][which]["travel"]:
        raise RuntimeError(f"case {case['id']} ({which}): the simulated axis diverged or lost track")
    idx = _sample_indices(xs.size, h, nsub * rig["log_every"], rig.get("jitter"), rng)
    t, q, f = _finish_log(idx * h, xs[idx], us[idx], rig["quant"], rig["noise"], rng)
    meta = {"saturated_pct": float(100 * np.mean(np.abs(us) >= 0.999 * ulim)) if np.isfinite(ulim) else 0.0,
            "track_err_rms": float(np.sqrt(np.mean((xs - np.repeat(r, nsub)) ** 2)))}
    return Run(t, q, f, 0.5 / f_ctrl, meta)


def core_friction(rig: dict[str, Any], effects: list[dict[str, Any]], with_viscous: bool = True) -> Any:
    """The core friction model of a ``core`` rig (its contact, with a planted Stribeck hump)."""
    fc, fv = rig["Fc"], (rig["Fv"] if with_viscous else 0.0)
    st = next((e for e in effects if e["name"] == "stribeck"), None)
    strib = g.Stribeck(fc, fc + st["dF"], st["vs"], st["delta"]) if st else g.Stribeck(fc, fc, 1.0, 1.0)
    c = rig["contact"]
    if c["model"] == "static":
        return g.StaticFriction(strib, fv)
    if c["model"] == "lugre":
        return g.LuGre(strib, c["sigma0"], c.get("sigma1", 0.0), fv)
    if c["model"] == "gms":
        return g.GMS(strib, c["k"], c["alpha"], c["c"], fv)
    if c["model"] == "maxwell":
        return g.MaxwellSlip(c["k"], c["w"], fv)
    raise ValueError(f"core has no contact {c['model']!r}")


def _simulate_core(rig: dict[str, Any], effects: list[dict[str, Any]], r: Array, rv: Array, ra: Array, f_ctrl: float,
                   ulim: float, rng: np.random.Generator) -> tuple[Array, Array, Array]:
    dt = 1.0 / f_ctrl
    gain = rig["gain"]
    tau = next((e["tau"] for e in effects if e["name"] == "input_delay"), 0.0)
    plant = g.Plant.from_mass(rig["M"], delay=tau, force_gain=gain)
    ctrl = rig["ctrl"]
    wb = 2 * np.pi * ctrl["fb"]
    lim = ulim / gain if np.isfinite(ulim) else np.inf
    if ctrl["kind"] == "pid":
        M = rig["M"]
        controller: Any = g.PID(3 * M * wb**2 / gain, M * wb**3 / gain, 3 * M * wb / gain, 1.0 / (10 * wb), -lim, lim)
    elif ctrl["kind"] == "pp":
        wv = 4 * wb
        controller = g.Cascade(wb, rig["M"] * wv / gain, -lim, lim)
    else:
        raise ValueError(f"core rigs use pid or pp, not {ctrl['kind']!r}")
    ff = ctrl.get("ff", {})
    feed = (ff.get("mass", 0.0) * ra + ff.get("fv", 0.0) * rv + ff.get("fc", 0.0) * np.tanh(rv / ff.get("veps", 1.0))) / gain
    t = np.arange(r.size) * dt
    load = np.zeros(r.size)
    for e in effects:
        if e["name"] == "offset":
            load += e["f0"]
        elif e["name"] == "ripple":
            load += e["amp"] * np.sin(2 * np.pi * e["freq"] * t + rng.uniform(0, 2 * np.pi))
        elif e["name"] == "square":
            load += e["amp"] * np.sign(np.sin(2 * np.pi * e["freq"] * t + rng.uniform(0, 2 * np.pi)))
        elif e["name"] not in ("stribeck", "presliding_hysteresis", "input_delay"):
            raise ValueError(f"core rigs cannot plant {e['name']!r}")
    res = g.simulate_closed_loop(plant, core_friction(rig, effects), controller, r, dt, feedforward=feed,
                                 load_force=load, quantization=rig["quant"], drive_limit=None if not np.isfinite(lim) else lim)
    return res.position, res.velocity, res.command * gain


# ------------------------------------------------------------------------------------------
# Real EMPS runs with planted effects.


def emps_dir() -> Path:
    """Where the EMPS files are: ``$GMSFRIC_EMPS_DIR``, else the shared data next to the repo."""
    env = os.environ.get("GMSFRIC_EMPS_DIR")
    if env:
        return Path(env)
    for cand in (Path(__file__).resolve().parents[3] / "shared" / "data" / "emps", Path("/work/shared/data/emps")):
        if cand.is_dir():
            return cand
    return Path("/work/shared/data/emps")


def _emps_load(name: str) -> dict[str, Array]:
    d = sio.loadmat(emps_dir() / name)
    return {k: np.asarray(v, float).ravel() for k, v in d.items() if not k.startswith("__")}


def compliance_filter(w2: float, z2: float, fs: float) -> tuple[Array, Array]:
    """Discrete ``H(s) = (2 z w s + w^2)/(s^2 + 2 z w s + w^2)`` (load motion / motor motion), bilinear."""
    b, a = signal.bilinear([2 * z2 * w2, w2**2], [1.0, 2 * z2 * w2, w2**2], fs)
    return b, a


def planted_force(effects: list[dict[str, Any]], t: Array, q: Array, v: Array, a: Array) -> Array:
    """Extra force of planted effects along a measured motion (``q``, ``v``, ``a`` estimates)."""
    f = np.zeros_like(t)
    s = np.sign(v)
    for e in effects:
        name = e["name"]
        if name == "stribeck":
            f += s * e["dF"] * stribeck_shape(np.abs(v) / e["vs"], e["kind"], e["delta"])
        elif name == "position_dependent_force":
            f += position_shape(q, np.asarray(e["shape"]))
        elif name == "position_dependent_friction":
            f += s * position_shape(q, np.asarray(e["shape"]))
        elif name == "friction_drift":
            d = drift_shape(t - t[0], e["kind"], e["T"])
            f += e["dF"] * d * s + e.get("dFv", 0.0) * d * v
        elif name == "presliding_hysteresis":
            f += g.simulate_friction(g.MaxwellSlip(e["k"], e["w"]), t, q)
        elif name == "compliance":
            b, aa = compliance_filter(math.sqrt(e["k2"] / e["m2"]), e["c2"] / (2 * math.sqrt(e["k2"] * e["m2"])), 1 / np.median(np.diff(t)))
            f += e["m2"] * signal.lfilter(b, aa, a)
        elif name in ("input_delay",):
            pass  # applied to the logged force below
        else:
            raise ValueError(f"cannot plant {name!r} on measured data")
    return f


def emps_run(case: dict[str, Any], which: str) -> Run:
    """A real EMPS run (estimation or pulses file) with the case's effects planted on the force."""
    files = case["files"]
    d = _emps_load(files[which])
    t, q = d["t"], d["qm"]
    f = d["gtau"][0] * d["vir"]
    dt = float(np.median(np.diff(t)))
    # our own motion estimate for planting (Savitzky-Golay, not the loop's Butterworth recipe)
    v = signal.savgol_filter(q, 31, 3, deriv=1, delta=dt)
    a = signal.savgol_filter(q, 31, 3, deriv=2, delta=dt)
    f = f + planted_force(case["effects"], t, q, v, a)
    tau = next((e["tau"] for e in case["effects"] if e["name"] == "input_delay"), 0.0)
    if tau:
        # the drive's force acts tau after the logged command: the log leads the physical force
        f = np.interp(t + tau, t, f)
    rng = np.random.default_rng(case["seed"] + (0 if which == "est" else 7919))
    f = f + case.get("extra_noise", 0.0) * rng.standard_normal(f.size)
    return Run(t, q, f, 0.5e-3, {})


# ------------------------------------------------------------------------------------------
# Files.

#: Factors from SI to the unit written in the file (the loop's `--*-unit` names).
TO_FILE = {"m": 1.0, "mm": 1e3, "um": 1e6, "rad": 1.0, "deg": 180.0 / np.pi, "s": 1.0, "ms": 1e3, "N": 1.0, "mN": 1e3, "kN": 1e-3, "Nm": 1.0}


def write_run(run: Run, fmt: dict[str, Any], path: Path) -> None:
    """Write a run as CSV or .mat in the file format of the case (names, units, force or command)."""
    cols = fmt["cols"]
    data = {cols["time"]: run.t * TO_FILE[fmt["time_unit"]], cols["position"]: run.q * TO_FILE[fmt["position_unit"]]}
    if fmt.get("command"):
        data[cols["command"]] = run.f / fmt["gain"]
    else:
        data[cols["force"]] = run.f * TO_FILE[fmt["force_unit"]]
    if path.suffix == ".mat":
        out: dict[str, Any] = {k: v.reshape(-1, 1) for k, v in data.items()}
        if fmt.get("command") and fmt.get("gain_name"):
            out[fmt["gain_name"]] = np.array([[fmt["gain"]]])
        sio.savemat(path, out)
    else:
        names = list(data)
        np.savetxt(path, np.column_stack([data[k] for k in names]), delimiter=",", header=",".join(names), comments="", fmt="%.10g")


def cli_args(fmt: dict[str, Any]) -> list[str]:
    """The column and unit arguments of ``gmsfric loop`` for a file format."""
    cols = fmt["cols"]
    args = ["--time", cols["time"], "--position", cols["position"]]
    if fmt.get("command"):
        args += ["--command", cols["command"], "--gain", fmt.get("gain_name") or repr(float(fmt["gain"]))]
    else:
        args += ["--force", cols["force"]]
    for key, flag in (("time_unit", "--time-unit"), ("position_unit", "--position-unit"), ("force_unit", "--force-unit")):
        if fmt.get(key) and not (fmt.get("command") and key == "force_unit"):
            unit = fmt[key]
            if key == "force_unit" and unit == "N" and fmt.get("position_unit") in ("rad", "deg"):
                unit = "N m"  # the file holds a torque (factor 1 either way): declare it as one
            args += [flag, unit]
    return args


def cross_check(nsub: int = 10) -> dict[str, float]:
    """The own integrator against the core on the same axis (20 kg, Coulomb 10 N, viscous 80 N s/m,
    PID at 10 Hz, 1 kHz, 10 s sweep, set-valued stiction): two independent implementations."""
    M, Fc, Fv, fctrl = 20.0, 10.0, 80.0, 1000
    r, rv, ra = trajectory({"kind": "sweep", "seed": 1, "travel": 0.1, "vmax": 0.1, "amax": 2.0}, 10.0, fctrl)
    rig = {"M": M, "Fc": Fc, "Fv": Fv, "f_ctrl": fctrl, "contact": {"model": "karnopp"}}
    C = controller_vector({"kind": "pid", "fb": 10.0}, M, fctrl, 0.0, np.inf)
    P, posf, posfric, ms_k, ms_w = mechanics_vector(rig, [], np.random.default_rng(0))
    xs, _, us = _integrate(r, rv, ra, nsub, 1.0 / fctrl, C, P, posf, posfric, ms_k, ms_w)
    wb = 2 * np.pi * 10.0
    pid = g.PID(3 * M * wb**2, M * wb**3, 3 * M * wb, 1.0 / (10 * wb))
    res = g.simulate_closed_loop(g.Plant.from_mass(M), g.StaticFriction(g.Stribeck(Fc, Fc, 1.0, 1.0), Fv), pid, r, 1.0 / fctrl)
    return {"tracking_rms_m": float(np.sqrt(np.mean(res.error**2))),
            "position_max_diff_m": float(np.max(np.abs(xs[::nsub] - res.position))),
            "force_rel_diff": float(np.linalg.norm(us[::nsub] - res.command) / np.linalg.norm(res.command))}
