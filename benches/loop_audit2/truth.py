"""Detectability in principle of each planted effect (uses the planted law only, never the tool).

Rule
----
For a planted effect E with its true force law (its exact column(s), true nonlinear parameters,
free linear coefficients), fit by least squares on the estimation run

    baseline:  f = M a + Fv v + Fc sign(v) + offset          (no offset with --baseline rigid)
    with E:    baseline + columns(E)

and evaluate both on the validation run: relative rms force error e = rms(f - X theta) / rms(f).
E is *detectable* when  gain = 1 - e_with / e_base >= 0.10  (all rows).  The same is reported on
"moving" rows (|v| > 1 % of the 99th-percentile speed; fit and evaluation on those rows; with a
planted delay, moving at t and at t + tau for every model compared).
input_delay has no column: the regressors are advanced by the true delay.  With two planted
effects, each one's gain is measured on top of the other's true column(s) (or advance).

Signals: the logged (quantised) position, resampled onto a uniform grid when the time stamps
are irregular; zero-phase 4th-order Butterworth (filtfilt) at fc = min(0.1 fs, 100 Hz); v and a
by central differences.  The force is filtered by the same zero-phase filter (parallel
filtering, as in IDIM); columns linear in the filtered motion (a, v) are used as they are,
every nonlinear column (sign(v), |v|, g(q), Maxwell-slip force, ...) is computed and then
passed through the same filter, so that force and regressors share one bandwidth.
Rows within two filter periods of either end are dropped.
"""
from __future__ import annotations

import math

import numba as nb
import numpy as np
from scipy import signal

DETECT_GAIN = 0.10


# ----------------------------------------------------------------------------------------------
def prepare(t, q, f, res):
    """uniform grid, zero-phase filtered motion, parallel-filtered force"""
    t = np.asarray(t, float)
    q = np.asarray(q, float)
    f = np.asarray(f, float)
    dts = np.diff(t)
    irregular = np.std(dts) > 1e-3 * np.mean(dts)
    if irregular:
        h = float(np.mean(dts))
        tu = np.arange(t[0], t[-1], h)
        q = np.interp(tu, t, q)
        f = np.interp(tu, t, f)
        t = tu
    else:
        h = float(np.mean(dts))
    fs = 1.0 / h
    fc = min(0.1 * fs, 100.0)
    sos = signal.butter(4, fc, fs=fs, output="sos")
    qf = signal.sosfiltfilt(sos, q)
    v = np.gradient(qf, h)
    a = np.gradient(v, h)
    ff = signal.sosfiltfilt(sos, f)
    ntrim = int(math.ceil(2.0 / fc * fs))
    keep = np.zeros(len(t), bool)
    keep[ntrim:len(t) - ntrim] = True
    vrest = 2.0 * res * fc
    sg = np.where(np.abs(v) > vrest, np.sign(v), 0.0)
    v99 = np.percentile(np.abs(v[keep]), 99)
    moving = keep & (np.abs(v) > 0.01 * v99)
    return dict(t=t, q=q, qf=qf, v=v, a=a, f=ff, sg=sg, keep=keep, moving=moving, sos=sos, fs=fs,
                fc=fc, h=h, irregular=bool(irregular))


@nb.njit(cache=True)
def maxwell_slip(q, k, D):
    n = q.shape[0]
    ne = k.shape[0]
    z = np.zeros(ne)
    out = np.empty(n)
    for j in range(n):
        dq = q[j] - q[j - 1] if j > 0 else 0.0
        F = 0.0
        for i in range(ne):
            z[i] += dq
            if z[i] > D[i]:
                z[i] = D[i]
            elif z[i] < -D[i]:
                z[i] = -D[i]
            F += k[i] * z[i]
        out[j] = F
    return out


def _pf_unit(x, law, xlo, xhi):
    xi = np.clip(2.0 * (x - xlo) / (xhi - xlo) - 1.0, -1.5, 1.5)
    if law["kind"] == "sine":
        return np.sin(2 * np.pi * x / law["per"] + law["phi"])
    if law["kind"] == "linear":
        return xi
    return 2.0 * xi * xi - 1.0


def _pg_unit(x, law):
    k = law["kind"]
    if k == "cogging":
        return np.sin(2 * np.pi * x / law["per"] + law["phi"])
    if k == "spring":
        return (x - law["x0"]) / law["per"]
    if k == "gravity":
        return np.sin(x + law["phi"])
    return np.tanh((x - law["x0"]) / law["per"])


def effect_columns(eff, law, S, rig):
    """true columns of one effect on the prepared signals S; (cols, filter_them)"""
    v, sg, qf, t = S["v"], S["sg"], S["qf"], S["t"]
    if eff == "asymmetric_friction":
        return [np.abs(v)], True
    if eff == "stribeck":
        x = np.abs(v / law["vs"])
        shp = np.exp(-x ** 1.5) if law["shape"] == "exp15" else 1.0 / (1.0 + x * x)
        return [sg * shp], True
    if eff == "presliding_hysteresis":
        D = np.asarray(law["D"], float)
        w = np.asarray(law["w"], float)
        return [maxwell_slip(S["q"], w / D, D)], True
    if eff == "position_dependent_friction":
        P = rig["P"]
        return [sg * _pf_unit(qf, law, P["x_lo"], P["x_hi"])], True
    if eff == "position_dependent_force":
        return [_pg_unit(qf, law)], True
    if eff == "friction_drift":
        h = np.exp(-t / law["T"]) if law["kind"] == "exp" else t / law["T"]
        return [h * sg, h * v], True
    if eff == "heating":
        al = 1.0 - math.exp(-S["h"] / law["tau"])
        m = signal.lfilter([al], [1.0, -(1.0 - al)], np.abs(v))
        return [m * sg, m * v], True
    if eff == "compliance":
        wn = 2 * math.pi * law["fn"]
        z = law["zeta"]
        # m2 (H - 1) a, H - 1 = -s^2 / (s^2 + 2 z wn s + wn^2), causal (physics)
        b, a = signal.bilinear([-1.0, 0.0, 0.0], [1.0, 2 * z * wn, wn * wn], fs=S["fs"])
        return [signal.lfilter(b, a, S["a"])], False
    if eff == "offset":
        return [np.ones_like(v)], False
    # outside the catalogue (informational only)
    if eff == "drag":
        return [v * np.abs(v)], True
    if eff == "ripple":
        w = 2 * math.pi * law["f"]
        return [np.sin(w * t), np.cos(w * t)], True
    if eff == "load_friction":
        return [np.abs(S["f"]) * sg], True
    return None, False


def _advance(cols, S, tau):
    t = S["t"]
    return [np.interp(t + tau, t, c) for c in cols]


def design(S, rig, effects, baseline):
    """regressor list for baseline + effects; delay handled by advancing everything"""
    cols = [S["a"], S["v"], signal.sosfiltfilt(S["sos"], S["sg"])]
    if baseline == "reference":
        cols.append(np.ones_like(S["v"]))
    for e in effects:
        if e == "input_delay":
            continue
        c, filt = effect_columns(e, rig["law"][e], S, rig)
        if c is None:
            return None
        if filt:
            c = [signal.sosfiltfilt(S["sos"], x) for x in c]
        cols.extend(c)
    if "input_delay" in effects:
        cols = _advance(cols, S, rig["law"]["input_delay"]["tau"])
    return np.column_stack(cols)


def _rows(S, rig, which):
    """the same rows for every model of a comparison; with a planted delay the rows must have
    their advanced sample inside the run and, for "moving", be moving at t and at t + tau (the
    command at t belongs to the motion at t + tau)"""
    r = S["keep"] if which == "all" else S["moving"]
    if "input_delay" in rig["law"]:
        tau = rig["law"]["input_delay"]["tau"]
        r = r & (S["t"] + tau < S["t"][-1] - S["h"])
        if which != "all":
            r = r & (np.interp(S["t"] + tau, S["t"], S["moving"].astype(float)) > 0.999)
    return r


def rel_error(SE, SV, rig, effects, baseline, which):
    XE = design(SE, rig, effects, baseline)
    XV = design(SV, rig, effects, baseline)
    if XE is None or XV is None:
        return float("nan")
    re, rv = _rows(SE, rig, which), _rows(SV, rig, which)
    A = XE[re]
    scale = np.sqrt(np.mean(A ** 2, axis=0))
    scale[scale == 0] = 1.0
    th, *_ = np.linalg.lstsq(A / scale, SE["f"][re], rcond=None)
    th = th / scale
    r = SV["f"][rv] - XV[rv] @ th
    return float(np.sqrt(np.mean(r ** 2)) / np.sqrt(np.mean(SV["f"][rv] ** 2)))


def detectability(est, val, rig, baseline="reference"):
    """est/val: dict(t, q, f) logged runs in SI.  Returns per-effect gains (all, moving) and the
    baseline errors.  Only the planted laws in rig['law'] are used."""
    res = rig["P"]["res"]
    SE = prepare(est["t"], est["q"], est["f"], res)
    SV = prepare(val["t"], val["q"], val["f"], res)
    planted = [e for e in rig["effects"]]
    out = dict(filter_hz=SE["fc"], irregular=SE["irregular"], effects={})
    for which in ("all", "moving"):
        out[f"base_err_{which}"] = rel_error(SE, SV, rig, [], baseline, which)
    for e in planted + ([rig["outside"]] if rig.get("outside") else []):
        others = [o for o in planted if o != e and o != rig.get("outside")]
        d = {}
        for which in ("all", "moving"):
            e0 = rel_error(SE, SV, rig, others, baseline, which)
            e1 = rel_error(SE, SV, rig, others + [e], baseline, which)
            d[f"err0_{which}"] = e0
            d[f"err1_{which}"] = e1
            d[f"gain_{which}"] = float(1.0 - e1 / e0) if e0 > 0 and np.isfinite(e1) else float("nan")
        d["detectable"] = bool(np.isfinite(d["gain_all"]) and d["gain_all"] >= DETECT_GAIN)
        d["detectable_moving"] = bool(np.isfinite(d["gain_moving"]) and d["gain_moving"] >= DETECT_GAIN)
        out["effects"][e] = d
    return out
