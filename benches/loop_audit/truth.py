"""Ground truth of an audit case: how much each planted effect *can* lower the held-out error.

The project's target counts recall only "at the strengths where its true regression column lowers
the held-out error by >= 10 % relative".  For each planted effect E of a case this module gives

    gain(E) = 1 - err_with / err_without

* ``err``: relative rms force error (:func:`gmsfric.loop.relative_error`) on the validation run's
  moving rows (``Signals.moving``), the model fitted by least squares on the estimation run's
  moving rows;
* ``err_with``: baseline ``M qdd + Fv qd + Fc sign(qd) + offset`` plus the true column of every
  planted effect; ``err_without``: the same for the rig without E (the other effects' columns).

The rig's friction is *multiplicative* (rigs.py: a scale ``s(q, t, heat)`` on the whole law), so
an effect's true column is ONE column: the rig's force law evaluated along the filtered measured
motion with all planted effects, minus the same law with E removed (as ``run.strip`` removes it).
It carries E's true nonlinear parameters and its interaction with the other effects; only its
coefficient is fitted.  When two planted effects scale each other (a multiplier times another
friction effect) the columns alone count their product twice; one more column, the law with all
minus the law with none minus the columns, makes the model the rig's own again (without it the
true model of a pair such as asymmetry + heating left 8.6 % error instead of 3.6 %).  ``sign(qd)`` stands for the rig's tanh (its eps is 1e-4 vmax).  Pre-sliding
elements are driven by the measured (raw) position, like the loop's own; heating's state is the
rig's low-pass of the speed, run along the filtered ``|qd|``; compliance is ``Ml (H(s) - 1) qdd``
with ``H`` the load's motion over the motor's.  An input delay is no column: every regressor is
advanced by the true delay (the force at t is explained by the motion at t + tau), and its gain
compares that with the unshifted model.  Every model also carries the controller's hold (half a
control period, physics of every run, never an effect).

``gain_clear`` is the same figure on the rows clear of reversals and stops (the loop's
``settled_rows`` and ``dip_resolution``), both models fitted again on the estimation rows clear
of them: where the loop confirms whole-motion effects.  Below a 1 kHz log the cut-off is the one
among the loop's candidates under which the true model fits the estimation run best (the loop too
chooses it on the estimation run).
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from scipy import signal

from gmsfric import models
from gmsfric.loop import Preprocessing, Signals, load_axis_data, relative_error
from gmsfric.loop.effects import dip_resolution, settled_rows

DETECTABLE = 0.10
HOLD = 0.5 / 5000.0   # half the controller period of rigs.py (F_CTRL = 5 kHz)


def law(rig: dict, planted: list, sig: Signals, T: float, drop: str | None = None) -> np.ndarray:
    """Full-rate force of the rig's friction, position force and compliance (no inertia, no
    offset) along the filtered measured motion, with the planted effects but ``drop``."""
    on = lambda e: e in planted and e != drop  # noqa: E731
    q, v, t = sig.q, sig.qd, sig.t
    sg = np.sign(v)
    s = np.ones_like(q)
    if on("position_dependent_friction"):
        x = np.sin(2 * np.pi * q / rig["pdf_period"] + rig["pdf_phase"]) if rig["pdf_kind"] == 1 \
            else 2 * q / rig["travel"]
        s *= 1 + rig["pdf_amp"] * x
    if on("friction_drift"):
        h = t / T if rig["drift_kind"] == 1 else 1 - np.exp(-t / rig["drift_tau"])
        s *= 1 + rig["drift_amp"] * h
    if on("heating"):
        a = math.exp(-sig.dt / rig["heat_tau"])
        m = signal.lfilter([1 - a], [1, -a], np.abs(v))   # the rig starts at rest, state 0
        s *= 1 - rig["heat_amp"] * np.minimum(m / (0.5 * rig["vmax"]), 1.5)
    ms = on("presliding_hysteresis")
    fc = rig["Fc"] - (sum(rig["ms_force"]) if ms else 0.0)   # the elements carry part of Fc
    ds = rig["fs_ratio"] * rig["Fc"] if on("stribeck") else 0.0
    asym = rig["asym"] if on("asymmetric_friction") else 0.0
    f = s * ((fc + ds * np.exp(-(v / rig["vs"]) ** 2)) * sg + rig["Fv"] * (v + asym * np.abs(v)))
    if ms:   # elements (stiffness F_i/Delta_i, break force F_i) on the measured position; unscaled
        w, d = np.asarray(rig["ms_force"]), np.asarray(rig["ms_delta"])
        f += models.simulate_friction(models.MaxwellSlip(k=list(w / d), w=list(w)), sig.t + 0.0,
                                      np.asarray(sig.data.position, dtype=float))
    if on("position_dependent_force"):
        k, A, ph = rig["pf_kind"], rig["pf_amp"], rig["pf_phase"]
        f += A * (np.sin(2 * np.pi * q / rig["pf_period"] + ph) if k == 1 else
                  2 * q / rig["travel"] if k == 2 else np.sin(q + ph))
    if on("compliance"):
        # rigs.simulate: motor Mm, load Ml on kspr, cspr.  Force on the motor = Mm qdd + Ml H qdd
        # = M qdd + Ml (H - 1) qdd, H = (2 z w s + w^2)/(s^2 + 2 z w s + w^2) of the load alone
        M, r = rig["M"], rig["comp_ratio"]
        Mm = M / (1 + r)
        Ml = M - Mm
        wn = 2 * np.pi * rig["comp_fn"]
        k_s, c_s = wn * wn * Mm * Ml / M, 2 * rig["comp_zeta"] * wn * Mm * Ml / M
        w2, z2 = math.sqrt(k_s / Ml), c_s / (2 * math.sqrt(k_s * Ml))
        b, a = signal.bilinear([-1.0, 0.0, 0.0], [1.0, 2 * z2 * w2, w2 * w2], fs=sig.fs)
        f += Ml * signal.lfilter(b, a, sig.qdd, zi=signal.lfilter_zi(b, a) * sig.qdd[0])[0]
    return f


def _X(sig: Signals, cols: list, shift: float) -> np.ndarray:
    """Decimated regression rows of baseline + ``cols``, all advanced by ``shift`` seconds."""
    X = np.column_stack([sig.qdd, sig.qd, np.sign(sig.qd), np.ones_like(sig.q)] + cols)
    X = np.column_stack([np.interp(sig.t + shift, sig.t, c) for c in X.T])
    return sig.decimate(X)


def _errors(se, sv, ce, cv, shift, rows_e, rows_v) -> tuple[float, float, np.ndarray]:
    """(estimation, held-out) relative errors (%) fitted on ``rows_e``, tested on ``rows_v``, and
    the coefficients."""
    Xe, Xv = _X(se, ce, shift), _X(sv, cv, shift)
    sc = np.linalg.norm(Xe[rows_e], axis=0)
    sc[sc == 0] = 1.0
    th = np.linalg.lstsq(Xe[rows_e] / sc, se.y[rows_e], rcond=None)[0] / sc
    return (relative_error(se.y[rows_e], Xe[rows_e] @ th), relative_error(sv.y[rows_v], Xv[rows_v] @ th), th)


def _signals(cdir: Path, units, pre: Preprocessing) -> tuple[Signals, Signals]:
    kw = dict(time="t", position="q", force="f", time_unit=units[0], position_unit=units[1],
              force_unit=units[2])
    se = Signals(load_axis_data(str(cdir / "est.csv"), **kw), pre)
    sv = Signals(load_axis_data(str(cdir / "val.csv"), **kw), se.pre, q_range=se.q_range,
                 rest_speed=se.rest_speed)
    return se, sv


def true_columns(rig: dict, effs: list, se: Signals, sv: Signals, T: float) -> tuple[list, list]:
    """Full-rate true columns (estimation, validation) of the rig with the effects ``effs``: one
    per effect but a delay (the law minus the law without it) and, when the effects scale each
    other (a multiplier times another friction effect), their interaction (the law minus the law
    with none, minus those columns), so that the model is the rig's own."""
    out = []
    for sig in (se, sv):
        full = law(rig, effs, sig, T)
        cols = [full - law(rig, effs, sig, T, drop=e) for e in effs if e != "input_delay"]
        out.append(cols + [full - law(rig, [], sig, T) - sum(cols, np.zeros_like(full))])
    (ce, cv), tot = out, np.linalg.norm(sum(out[0][:-1], np.zeros_like(se.q)))
    if not np.linalg.norm(ce[-1]) > 1e-6 * tot:   # additive effects: no interaction column
        ce, cv = ce[:-1], cv[:-1]
    return ce, cv


def case_gains(cdir: Path) -> dict:
    """Per planted effect of the case in ``cdir``: gain, gain_clear, detectable (+ context)."""
    tr = json.loads((cdir / "truth.json").read_text())
    rig, planted, T = tr["rig"], tr["planted"], tr["T"]
    tau = rig["delay"] if "input_delay" in planted else 0.0

    def err(se, sv, effs, clear=None):
        """(est, held-out) errors and coefficients of the true model of the rig with ``effs``."""
        ce, cv = true_columns(rig, effs, se, sv, T)
        shift = HOLD + (tau if "input_delay" in effs else 0.0)
        return _errors(se, sv, ce, cv, shift, *(clear or (se.moving, sv.moving)))

    cands = Preprocessing().cutoffs(rig["fs_log"])
    tried = [_signals(cdir, tr["units"], Preprocessing(cutoff_hz=c) if len(cands) > 1 else Preprocessing())
             for c in cands]
    # the cut-off under which the true model fits the estimation run best (one at >= 1 kHz)
    se, sv = min(tried, key=lambda ss: err(*ss, planted)[0])
    clear = (settled_rows(se) & (np.abs(se.rows["qd"]) >= dip_resolution(se)) & se.moving,
             settled_rows(sv) & (np.abs(sv.rows["qd"]) >= dip_resolution(se)) & sv.moving)
    full = err(se, sv, planted)
    out = {"cutoff_hz": se.cutoff, "moving_rows": [int(se.moving.sum()), int(sv.moving.sum())],
           "clear_rows": [int(clear[0].sum()), int(clear[1].sum())],
           "baseline_err": err(se, sv, [])[1], "true_model_err": full[1], "effects": {}}
    for e in planted:
        out["effects"][e] = {}
        if e != "input_delay":   # a right column comes out near 1: it carries the true scale
            out["effects"][e]["coef"] = round(float(full[2][4 + [x for x in planted if x != "input_delay"].index(e)]), 3)
    for rows, key in ((None, "gain"), (clear, "gain_clear")):
        if rows is not None and min(rows[0].sum(), rows[1].sum()) < 20:
            continue
        with_ = err(se, sv, planted, rows)[1]
        for e in planted:
            without = err(se, sv, [x for x in planted if x != e], rows)[1]
            out["effects"][e][key] = round(1 - with_ / without, 4)
    for d in out["effects"].values():
        d["detectable"] = bool(d["gain"] >= DETECTABLE)
    return out


def cached_gains(cdir: Path, fresh: bool = False) -> dict:
    """:func:`case_gains`, cached in ``cdir/detect.json``."""
    p = cdir / "detect.json"
    if p.exists() and not fresh:
        try:
            return json.loads(p.read_text())
        except json.JSONDecodeError:
            pass   # a run cut off while writing it: computed again
    g = case_gains(cdir)
    p.write_text(json.dumps(g, indent=1))
    return g


if __name__ == "__main__":
    import sys
    for d in sys.argv[1:]:
        g = case_gains(Path(d))
        print(d, json.dumps(g))
