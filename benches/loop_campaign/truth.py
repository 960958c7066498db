"""Ground truth of a case: is each planted effect detectable in principle?

An effect is *detectable* when adding its own true regression column(s) -- its exact functional
form with the true nonlinear parameters, only the linear coefficients fitted -- to the baseline
``M qdd + Fv qd + Fc sign(qd) [+ offset]`` lowers the held-out relative force error by at least
10 % relative.  With several planted effects the gain of each is measured on top of all the
others' true columns (its marginal contribution).  A planted input delay is the baseline's
regressors advanced by the true delay rather than an extra column.

Preprocessing reuses the loop's public API (:class:`gmsfric.loop.Signals`, the EMPS recipe:
filtering, differences, edges, decimation; below 1 kHz the cut-off under which the true model
fits the estimation run best, :func:`true_signals`); the least squares and the error are computed here.
A second, informative figure leaves standstill rows out (``gain_moving``,
``detectable_moving``): at rest a stuck axis carries any holding force up to the break-away level,
which ``sign(qd)`` (of a filtered, ringing velocity) cannot represent and which can hide or fake an
effect.  Every run also carries the sampling hold (half a controller period), which the true model
includes as physics of the rig, never as an effect.  A third figure (``gain_beyond_null``,
``detectable_beyond_null``, moving rows) measures an effect against what the loop tests it
against: pre-sliding on top of the switch of friction where the measured position reverses (a
block one position resolution wide: every contact does that, and it is a sharper Coulomb term than
``sign`` of the filtered velocity), an input delay against the best timing shift within one
sample (the loop's alignment); for the other effects it equals ``gain_moving``.  Logs with irregular time stamps are
linearly resampled onto a uniform grid at their median step.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import signal

import gmsfric as g
from gmsfric.loop import Preprocessing, Signals
from gmsfric.loop.data import AxisData

from .rigs import Run, compliance_filter, drift_shape, position_shape, stribeck_shape

Array = NDArray[np.float64]

#: Relative decrease of the held-out error that makes an effect detectable.
DETECTABLE = 0.10


def uniform(run: Run) -> tuple[Array, Array, Array, float]:
    """``t, q, f`` on a uniform grid (resampled at the median step when the log jitters)."""
    d = np.diff(run.t)
    dt = float(np.median(d))
    if d.max() - d.min() <= 1e-6 * dt:
        return run.t, run.q, run.f, 0.0
    tu = np.arange(run.t[0], run.t[-1], dt)
    return tu, np.interp(tu, run.t, run.q), np.interp(tu, run.t, run.f), float(d.max() / d.min())


def signals(est: Run, val: Run, pre: Preprocessing = Preprocessing()) -> tuple[Signals, Signals]:
    """The loop's preprocessing of both runs (validation bases on the estimation travel)."""
    te, qe, fe, _ = uniform(est)
    tv, qv, fv, _ = uniform(val)
    se = Signals(AxisData(te, qe, fe, source="est"), pre)
    sv = Signals(AxisData(tv, qv, fv, source="val"), pre, q_range=se.q_range)
    return se, sv


def effect_columns(e: dict[str, Any], sig: Signals) -> list[Array]:
    """Full-rate true regression columns of one effect on one run (empty for a delay)."""
    q, qd, qdd, t = sig.q, sig.qd, sig.qdd, sig.t
    s = np.sign(qd)
    name = e["name"]
    if name == "asymmetric_friction":
        cols = []
        if e.get("dFv", 0.0):
            cols.append(np.abs(qd))
        if e.get("dFc", 0.0):
            cols.append(np.abs(s))
        return cols
    if name == "stribeck":
        return [s * stribeck_shape(np.abs(qd) / e["vs"], e["kind"], e["delta"])]
    if name == "presliding_hysteresis":
        return [g.simulate_friction(contact_model(e), t, q)]
    if name == "position_dependent_friction":
        return [s * position_shape(q, np.asarray(e["shape"]))]
    if name == "position_dependent_force":
        return [position_shape(q, np.asarray(e["shape"]))]
    if name == "friction_drift":
        d = drift_shape(t, e["kind"], e["T"])
        return [s * d] + ([qd * d] if e.get("dFv", 0.0) else [])
    if name == "compliance":
        w2 = math.sqrt(e["k2"] / e["m2"])
        b, a = compliance_filter(w2, e["c2"] / (2 * math.sqrt(e["k2"] * e["m2"])), sig.fs)
        return [signal.lfilter(b, a, qdd)]
    if name == "offset":
        return [np.ones_like(q)]
    if name == "input_delay":
        return []
    if name == "drag":
        return [qd * np.abs(qd)]
    if name == "reversal_switch":
        return [switch_column(sig)]
    if name in ("ripple", "square", "backlash"):
        return []  # no fixed column: the phase changes between runs, or no closed form
    raise ValueError(f"no true column for {name!r}")


def switch_column(sig: Signals) -> Array:
    """Friction of unit level switching where the measured (raw) position reverses: a Maxwell-slip
    block one encoder step wide (the loop's contact resolution), the loop's null for pre-sliding."""
    return g.simulate_friction(g.MaxwellSlip([1.0 / sig.contact_resolution], [1.0]), sig.t, np.asarray(sig.data.position, dtype=float))


def contact_model(e: dict[str, Any]) -> Any:
    """The friction-free-of-viscosity contact whose force along the motion is the true column."""
    if e["model"] == "maxwell":
        return g.MaxwellSlip(e["k"], e["w"])
    if e["model"] == "gms":
        fc = e["fc"]
        return g.GMS(g.Stribeck(fc, fc, 1.0, 1.0), e["k"], e["alpha"], e["c"])
    if e["model"] == "lugre":
        fc = e["fc"]
        return g.LuGre(g.Stribeck(fc, fc, 1.0, 1.0), e["sigma0"], e.get("sigma1", 0.0))
    raise ValueError(f"no contact column for {e['model']!r}")


def _rows(cols: list[Array], sig: Signals, shift: float) -> Array:
    X = np.column_stack(cols)
    if shift:
        ts = sig.t + shift
        X = np.column_stack([np.interp(ts, sig.t, X[:, j]) for j in range(X.shape[1])])
    return sig.decimate(X)


def _base_columns(sig: Signals, with_offset: bool) -> list[Array]:
    cols = [sig.qdd, sig.qd, np.sign(sig.qd)]
    return cols + ([np.ones_like(sig.q)] if with_offset else [])


#: With ``moving=True``, rows slower than this fraction of the estimation run's 99th-percentile
#: speed are left out of fit and error (standstill: set-valued stiction, holding forces).
STANDSTILL = 0.01


def errors(se: Signals, sv: Signals, effects: list[dict[str, Any]], shift: float, with_offset: bool,
           moving: bool = False) -> tuple[float, float]:
    """Estimation and held-out relative errors (%) of baseline + effects' true columns."""
    ce = _base_columns(se, with_offset) + [c for e in effects for c in effect_columns(e, se)]
    cv = _base_columns(sv, with_offset) + [c for e in effects for c in effect_columns(e, sv)]
    Xe, Xv, ye, yv = _rows(ce, se, shift), _rows(cv, sv, shift), se.y, sv.y
    if moving:
        v_min = STANDSTILL * np.percentile(np.abs(se.rows["qd"]), 99)
        me, mv = np.abs(se.rows["qd"]) >= v_min, np.abs(sv.rows["qd"]) >= v_min
        Xe, ye, Xv, yv = Xe[me], ye[me], Xv[mv], yv[mv]
    scale = np.sqrt((Xe**2).sum(axis=0))
    scale[scale == 0] = 1.0
    theta = np.linalg.lstsq(Xe / scale, ye, rcond=None)[0] / scale
    err = lambda X, y: float(100 * np.linalg.norm(y - X @ theta) / np.linalg.norm(y))  # noqa: E731
    return err(Xe, ye), err(Xv, yv)


def true_signals(case: dict[str, Any], est: Run, val: Run) -> tuple[Signals, Signals]:
    """Both runs preprocessed as the truth measures them.  At 1 kHz and above with the recipe's
    filter; below, where the loop chooses its cut-off on the estimation run, with the one of the
    same cut-offs under which the true model (planted and native columns, true delay) fits the
    estimation run best (the recipe's ``fs/10`` lags the force on slow logs and would inflate
    every error)."""
    cutoffs = Preprocessing().cutoffs(1.0 / float(np.median(np.diff(uniform(est)[0]))))
    if len(cutoffs) == 1:
        return signals(est, val)
    effects = case.get("native", []) + case["effects"]
    delay = est.hold + next((e["tau"] for e in effects if e["name"] == "input_delay"), 0.0)
    off = case.get("baseline", "reference") == "reference"
    tried = [signals(est, val, Preprocessing(cutoff_hz=c)) for c in cutoffs]
    return min(tried, key=lambda ss: errors(ss[0], ss[1], effects, delay, off, moving=True)[0])


def ground_truth(case: dict[str, Any], est: Run, val: Run) -> dict[str, Any]:
    """Per planted effect: marginal and alone held-out gains, detectability; plus context."""
    se, sv = true_signals(case, est, val)
    off = case.get("baseline", "reference") == "reference"
    hold = est.hold
    native = case.get("native", [])
    planted = case["effects"]

    def err(effs: list[dict[str, Any]], moving: bool = False) -> tuple[float, float]:
        d = next((e["tau"] for e in effs if e["name"] == "input_delay"), 0.0)
        return errors(se, sv, native + effs, hold + d, off, moving)

    base, base_m = err([]), err([], True)
    full, full_m = err(planted), err(planted, True)
    out: dict[str, Any] = {
        "baseline_err": base, "true_model_err": full, "baseline_err_moving": base_m, "true_model_err_moving": full_m,
        "effects": {}, "fs": se.fs, "rows": se.n_rows, "jitter_ratio": uniform(est)[3], "cutoff_hz": se.cutoff,
    }
    def beyond_null(e: dict[str, Any], rest: list[dict[str, Any]], full_val: float) -> float:
        """Marginal held-out gain (moving rows) of ``e`` against the loop's null for it."""
        if e["name"] == "presliding_hysteresis":
            null = err(rest + [{"name": "reversal_switch"}], True)[1]
            return (null - err(planted + [{"name": "reversal_switch"}], True)[1]) / null
        if e["name"] == "input_delay":
            d = next((x["tau"] for x in rest if x["name"] == "input_delay"), 0.0)
            fits = [errors(se, sv, native + rest, k / (10 * se.fs) + d, off, True) for k in range(11)]
            null = min(fits)[1]  # the shift the estimation rows choose
            return (null - full_val) / null
        return float("nan")

    for e in planted:
        rest = [x for x in planted if x is not e]
        without = err(rest) if rest else base
        without_m = err(rest, True) if rest else base_m
        alone = err([e])
        marginal = (without[1] - full[1]) / without[1]
        marginal_m = (without_m[1] - full_m[1]) / without_m[1]
        over_null = beyond_null(e, rest, full_m[1])
        over_null = marginal_m if not np.isfinite(over_null) else over_null
        out["effects"][e["name"]] = {
            "gain": round(float(marginal), 4),
            "gain_alone": round(float((base[1] - alone[1]) / base[1]), 4),
            "gain_moving": round(float(marginal_m), 4),
            "est_err_alone": [round(base[0], 3), round(alone[0], 3)],
            "detectable": bool(marginal >= DETECTABLE),
            "detectable_moving": bool(marginal_m >= DETECTABLE),
            "gain_beyond_null": round(float(over_null), 4),
            "detectable_beyond_null": bool(over_null >= DETECTABLE),
        }
    info: dict[str, float] = {}
    for e in case.get("outside", []):
        cols = effect_columns(e, se)
        if cols:
            info[e["name"]] = round(float((base[1] - err([e])[1]) / base[1]), 4)
        if e["name"] == "backlash":
            # the load behind the gap rides on a spring: engaged, that is the catalogue's compliance
            spring = err([dict(name="compliance", m2=e["m2"], k2=e["k2"], c2=e["c2"])])
            info["latent_compliance"] = round(float((base[1] - spring[1]) / base[1]), 4)
    contact = case.get("rig", {}).get("contact", {})
    if contact.get("model") in ("maxwell", "gms", "lugre") and not any(e["name"] == "presliding_hysteresis" for e in planted):
        # the rig's own contact has an elastic range: its pre-sliding, when detectable given the
        # planted effects, is the rig's and not a false effect (on clean rigs as on the others)
        latent = err(planted + [dict(contact, name="presliding_hysteresis")])
        info["latent_presliding"] = round(float((full[1] - latent[1]) / full[1]), 4)
    out["info"] = info
    return out
