"""Catalogue columns against what the data can resolve: pre-sliding elements follow the measured
position (not the zero-phase filtered one), and a low-speed dip of friction must be wider than
the blur of the filtered velocity through a reversal."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gmsfric.loop.data import AxisData
from gmsfric.loop import LoopConfig, run_loop
from gmsfric.loop.effects import (CATALOGUE, COMPLIANCE_GRID_ZETAS, DIP_BLUR_MARGIN, _compliance_variants, _delay, _play, _presliding, _stribeck, _stribeck_ok,
                                   detection_limits, dip_resolution, resonance_limit, stribeck_fall, velocity_resolution)
from gmsfric.loop.rigs import Rig, simulate_rig
from gmsfric.loop.idim import LinearModel, Signals

FS = 1000.0
RES = 1e-7  # encoder step, m


def _stick_at_reversal() -> tuple[Signals, np.ndarray]:
    """A quantised axis that decelerates to a stop, sticks for 0.2 s at the turning point and
    departs at a constant acceleration; returns the signals and the last 20 ms of the stick, where
    the raw position is still constant and the zero-phase filtered one already moves back."""
    t = np.arange(0.0, 4.0, 1.0 / FS)
    a = 2.0  # m/s^2: the force built up while stuck throws the axis off
    q = 0.01 - 0.5 * a * np.where(t < 1.9, 1.9 - t, np.where(t > 2.1, t - 2.1, 0.0)) ** 2
    q = np.round(q / RES) * RES
    f = 5.0 * np.sign(np.gradient(q)) + 0.01 * np.random.default_rng(0).standard_normal(t.size)
    s = Signals(AxisData(t, q, f, source="stick"))
    held = (t > 2.08) & (t < 2.1)
    assert np.ptp(q[held]) == 0.0 and np.ptp(s.q[held]) > RES  # the filter leaks the departure into the stick
    return s, held


def test_presliding_element_holds_while_the_axis_sticks():
    s, held = _stick_at_reversal()
    for delta in (2 * RES, 5 * RES, 20 * RES):
        col = _play(s, delta)
        assert np.all(np.abs(col) <= 1.0 + 1e-12)
        # pre-sliding is displacement while the contact holds: no displacement, no change
        assert np.ptp(col[held]) == 0.0, delta
        # and it does switch when the axis moves back (it is not a constant)
        assert col[-1] == pytest.approx(-col[int(1.5 * FS)]) and abs(col[-1]) == pytest.approx(1.0)


def test_presliding_grid_starts_at_two_resolution_steps():
    s, _ = _stick_at_reversal()
    variants = _presliding(LinearModel([]), s, np.zeros(s.n_rows))
    assert variants
    terms = [t for m in variants for t in m.terms if t.name == "presliding_hysteresis"]
    # every variant carries the switch (one resolution step, tested as the null) ...
    assert all(t.hyper_names[0] == "Delta_switch" and t.hyper[0] == s.resolution for t in terms)
    # ... and blocks from two resolution steps of the raw position that drives them
    assert min(min(t.hyper[1:]) for t in terms) == pytest.approx(2 * s.resolution)
    assert max(max(t.hyper[1:]) for t in terms) <= 0.01 * np.ptp(s.q) * (1 + 1e-12)


def test_the_reported_detection_limits_are_the_ranges_the_variants_span():
    """What the report says a log can show is what the loop tries on it: the narrowest pre-sliding
    block, the shortest delay, the narrowest Stribeck curve and the band of resonances of the
    variants themselves, in SI with their units (rotary: rad, rad/s)."""
    s, _ = _stick_at_reversal()
    empty, r = LinearModel([]), np.zeros(s.n_rows)
    lim = detection_limits(s)

    def hyper(variants, name):
        return [t.hyper for m in variants for t in m.terms if t.name == name]

    blocks = [h for hs in hyper(_presliding(empty, s, r), "presliding_hysteresis") for h in hs[1:]]
    assert lim["presliding_hysteresis"]["smallest_break_displacement"] == pytest.approx(min(blocks))
    assert lim["presliding_hysteresis"]["largest_break_displacement"] == pytest.approx(max(blocks))
    assert lim["position_resolution"]["value"] == s.resolution and lim["position_resolution"]["unit"] == "m"
    delays = [m.delay for m in _delay(empty, s, r)]
    assert lim["input_delay"]["smallest_delay"] == pytest.approx(min(delays)) and lim["input_delay"]["smallest_delay"] > s.dt
    widths = [h[0] for h in hyper(_stribeck(empty, s, r), "stribeck")]
    assert lim["stribeck"]["smallest_stribeck_speed"] == pytest.approx(min(widths))
    freqs = [h[0] for h in hyper(_compliance_variants(empty, s, r), "compliance")]
    assert (lim["compliance"]["lowest_resonance"], lim["compliance"]["highest_resonance"]) == pytest.approx((min(freqs), max(freqs)))
    assert all(e["looked_for"] for k, e in lim.items() if "looked_for" in e)
    rot = detection_limits(s, rotary=True)
    assert rot["presliding_hysteresis"]["unit"] == "rad" and rot["stribeck"]["unit"] == "rad/s" and rot["compliance"]["unit"] == "Hz"
    # a travel of a few encoder steps leaves pre-sliding nothing to fit: said so, not a range
    t = np.arange(0.0, 4.0, 1.0 / FS)
    q = np.round(3 * RES * np.sin(2 * np.pi * 0.5 * t) / RES) * RES
    short = Signals(AxisData(t, q, np.sign(np.cos(2 * np.pi * 0.5 * t)), source="short"))
    assert detection_limits(short)["presliding_hysteresis"]["looked_for"] is False
    assert _presliding(empty, short, np.zeros(short.n_rows)) == []


def _params(fc: float, ds: float, vs: float) -> dict[str, dict[str, float]]:
    return {"Fc": {"value": fc, "std": 0.1}, "Fs_minus_Fc": {"value": ds, "std": 0.1}, "vs": {"value": vs, "std": float("nan")}}


def test_a_dip_mostly_inside_the_filter_blur_is_not_a_stribeck_curve():
    s, _ = _stick_at_reversal()
    dip = dip_resolution(s)
    assert dip >= velocity_resolution(s)  # a dip needs more room than a hump
    narrow = 0.5 * (velocity_resolution(s) + dip) if dip > velocity_resolution(s) else 0.9 * dip
    why = _stribeck_ok(_params(5.0, -2.0, narrow), s)
    assert why is not None and "dip" in why
    # the same width as a hump (friction higher at rest) is fine: blur never makes a hump
    assert _stribeck_ok(_params(5.0, +2.0, narrow), s) is None
    # a dip that keeps at least half its depth beyond the blur (with its margin) is a friction
    # curve: exp(-blur / vs) >= 1/2 for vs >= blur / ln 2 ...
    blur = DIP_BLUR_MARGIN * dip
    assert DIP_BLUR_MARGIN > 1.0
    assert _stribeck_ok(_params(5.0, -2.0, 1.05 * blur / np.log(2.0)), s) is None
    # ... one only a little narrower is mostly inside it
    assert "less than half" in _stribeck_ok(_params(5.0, -2.0, 0.95 * blur / np.log(2.0)), s)
    # the friction at rest must stay positive whatever the width
    assert "not positive" in _stribeck_ok(_params(5.0, -6.0, 10 * dip), s)


def test_a_hump_the_viscous_slope_outweighs_is_not_a_stribeck_curve():
    s, _ = _stick_at_reversal()
    vs, ds = 0.1 * s.v_scale, 2.0
    p = _params(5.0, ds, vs)
    # without viscous friction the curve falls by (nearly) all of Fs - Fc
    assert stribeck_fall(p, s.v_scale) == pytest.approx(ds * (1.0 - np.exp(-10.0)), rel=1e-9)  # delta = 1
    # a gentle slope leaves most of the fall: still a Stribeck curve
    assert _stribeck_ok({**p, "Fv": {"value": 0.2 * ds / vs, "std": 0.1}}, s) is None
    # a slope steeper than the hump's steepest descent: friction only rises with speed
    steep = {**p, "Fv": {"value": 2.0 * ds / vs, "std": 0.1}}
    assert stribeck_fall(steep, s.v_scale) == 0.0
    assert "never falls" in _stribeck_ok(steep, s)
    # an asymmetry counts in the direction where the viscous slope is smaller
    asym = {**steep, "dFv_asym": {"value": 1.9 * ds / vs, "std": 0.1}}
    assert _stribeck_ok(asym, s) is None


def test_a_drag_that_grows_with_the_square_of_the_speed_is_not_named_stribeck():
    """A v|v| drag (outside the catalogue) bends the friction curve upwards; a hump plus more
    viscous friction fits it, but never makes the friction fall, so no Stribeck curve is named."""
    rig = Rig(seed=4, fs=1000.0, duration=16.0)
    d = simulate_rig(rig)
    qd = np.gradient(d.position, d.t)
    v = float(np.percentile(np.abs(qd), 99))
    drag = 2.0 * rig.fc * qd * np.abs(qd) / v**2
    res = run_loop(AxisData(d.t, d.position, d.force + drag, source="drag rig"), None, LoopConfig(progress=False, effects=("stribeck",)))
    assert "stribeck" not in res.effects


def test_presliding_is_still_found_when_the_position_is_noisy_rather_than_quantised():
    # the elements follow the raw position: analog noise (2 um on an 80 mm travel, no encoder
    # steps) must not hide real pre-sliding nor break the fit
    from gmsfric.loop import LoopConfig, run_loop
    from gmsfric.loop.rigs import Rig, rig_pair

    est, val = rig_pair(Rig(effect="presliding_hysteresis", seed=13, fs=500.0, mass=30.0, travel=0.08, duration=18.0, quantization=1e-9))
    rng = np.random.default_rng(1)

    def noisy(d: AxisData) -> AxisData:
        return AxisData(d.t, d.position + 2e-6 * rng.standard_normal(d.position.size), d.force, source=d.source)

    res = run_loop(noisy(est), noisy(val), LoopConfig(progress=False))
    result = res.to_dict()
    assert result["final"]["effects"] == ["presliding_hysteresis"]
    # the contact's friction is all in its elements: no break force significantly negative
    p = result["final"]["parameters"]
    assert all(v["value"] > -2 * v["std"] for k, v in p.items() if k.startswith("w_"))
    assert result["final"]["validation_error_pct"] < 0.7 * result["baseline"]["validation_error_pct"]


@pytest.mark.parametrize("fs", [250.0, 1000.0, 5000.0])
def test_no_resonance_is_fitted_above_the_filter_cut_off(fs):
    """The zero-phase filter removes what lies above its cut-off from force and motion alike: a
    resonance there would fit the filter's transition band."""
    t = np.arange(0.0, 6.0, 1.0 / fs)
    q = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    s = Signals(AxisData(t, q, 10.0 * np.sign(np.cos(2 * np.pi * 0.5 * t)), source="sine"))
    fns = [tm.hyper[0] for m in _compliance_variants(LinearModel([]), s, np.zeros(s.n_rows)) for tm in m.terms]
    assert fns and max(fns) <= s.cutoff * (1 + 1e-12) and max(fns) <= 0.4 * s.fs / s.dec * (1 + 1e-12)
    assert CATALOGUE["compliance"].refine(s)[0][1] <= s.cutoff


def test_heating_is_refused_when_a_memory_shorter_than_a_thermal_one_fits_best():
    """Heating is friction that follows the speed low-passed over seconds.  On a rig whose
    friction follows the current speed (a v|v| drag), a memory of 0.1 s fits the estimation rows
    best: heating is then refused, not replaced by its nearest thermal variant (which absorbed the
    drag on the campaign's drag rigs).  On a rig with heating, a thermal memory fits best."""
    from gmsfric.loop.select import _best_variant, _residual_rows, stage_baseline, stage_prepare

    rig = Rig(seed=4, fs=1000.0, duration=16.0)
    d = simulate_rig(rig)
    qd = np.gradient(d.position, d.t)
    v = float(np.percentile(np.abs(qd), 99))
    cfg = LoopConfig(progress=False)
    split, chunk = stage_prepare(AxisData(d.t, d.position, d.force + 2.0 * rig.fc * qd * np.abs(qd) / v**2, source="drag"), None, cfg)
    st = stage_baseline(split, chunk, cfg)
    _, r_est = _residual_rows(st, cfg)
    m, why = _best_variant(CATALOGUE["heating"], st.model, st, cfg, r_est)
    assert m is None and "shorter than a thermal one" in why

    res = run_loop(simulate_rig(Rig(effect="heating", seed=1, fs=1000.0, duration=24.0)), None, LoopConfig(progress=False, effects=("heating",)))
    assert res.effects == ["heating"] and res.final.params()["heating_tau_s"]["value"] >= 1.0


def test_settled_rows_keep_clear_of_reversals_and_stops_by_the_filters_settling_time():
    """Settled rows are as far from each reversal as the decimation filter rings over (1 % of a
    step), which exceeds the velocity filter's settling at the recipe's 100 Hz rows."""
    from gmsfric.loop.effects import REVERSAL_SETTLING_PERIODS, settled_rows
    from gmsfric.loop.idim import decimation_settling_rows

    fs = 1000.0
    t = np.arange(0.0, 12.0, 1.0 / fs)
    q = 0.05 * np.sin(2 * np.pi * 0.25 * t)
    s = Signals(AxisData(t, q, np.cos(t), source="sine"))
    keep = settled_rows(s)
    tr = s.rows["t"]
    reversals = (np.arange(1, 7) - 0.5) * 2.0  # qd = 0 at t = 1, 3, 5, ... s
    dist = np.min(np.abs(tr[:, None] - reversals[None, :]), axis=1)
    row_dt = s.dt * s.dec
    # the decimation filter (order-8 Chebyshev) rings longer than the velocity filter settles
    assert decimation_settling_rows(s.dec) * row_dt > REVERSAL_SETTLING_PERIODS / s.cutoff
    margin = decimation_settling_rows(s.dec) * row_dt
    assert not keep[dist < margin].any()
    # rows clear of the reversals and of the slow rows around them are all kept
    assert keep[(dist > margin + 2 * row_dt) & s.moving].all()


def _creeping_axis(seed: int, v_creep: float = 4e-4, vmax: float = 0.1, n_moves: int = 16) -> AxisData:
    """An axis whose reversals are crossed slowly: between fast moves (``vmax``) it creeps at
    ``v_creep`` (0.4 % of ``vmax``, under the standstill speed) over 60-100 um, across a
    Maxwell-slip contact of 20 N with break displacements of 5, 20 and 60 um."""
    from gmsfric import models

    rng = np.random.default_rng(seed)
    dt = 1.0 / FS
    pieces = []
    ramp = v_creep * np.sin(0.5 * np.pi * np.arange(0.0, 0.02, dt) / 0.02)
    for k in range(n_moves):
        t_fast = rng.uniform(0.6, 1.0)
        creep = np.full(int(rng.uniform(0.15, 0.25) / dt), v_creep)
        tb = np.arange(0.0, t_fast, dt)
        bell = v_creep + (vmax - v_creep) * 0.5 * (1.0 - np.cos(2.0 * np.pi * tb / t_fast))
        rest = np.zeros(int(rng.uniform(0.1, 0.3) / dt))
        pieces.append((-1.0) ** k * np.concatenate([ramp, creep, bell, creep, ramp[::-1], rest]))
    v = np.concatenate(pieces)
    t = dt * np.arange(v.size)
    q = np.cumsum(v) * dt
    qd = np.gradient(q, dt)
    contact = models.MaxwellSlip(k=[8.0 / 5e-6, 6.0 / 20e-6, 6.0 / 60e-6], w=[8.0, 6.0, 6.0])
    force = 20.0 * np.gradient(qd, dt) + 80.0 * qd + models.simulate_friction(contact, t, q) + 0.05 * rng.standard_normal(t.size)
    return AxisData(t, np.round(q / RES) * RES, force, source=f"creeping axis {seed}")


def test_presliding_crossed_slower_than_the_standstill_speed_is_judged_where_the_axis_creeps():
    # the elastic range is crossed at 0.4 % of the top speed, under the standstill speed (1 %):
    # on the moving rows alone the blocks have nothing to explain
    est, val = _creeping_axis(1), _creeping_axis(2)
    only = dict(progress=False, effects=("presliding_hysteresis",))
    found = run_loop(est, val, LoopConfig(**only))
    assert found.effects == ["presliding_hysteresis"]
    step = next(s for s in found.steps if s.accepted)
    assert step.evidence["judged_on"].startswith("moving and creeping rows")
    assert found.standstill["estimation_rows_creeping_pct"] > 10.0
    p = found.to_dict()["final"]["parameters"]
    weights = {k: v["value"] for k, v in p.items() if k.startswith("w_")}
    assert all(w > -2 * p[k]["std"] for k, w in weights.items())
    # fitted on the rows it describes, the contact's 20 N is split between Coulomb and blocks
    assert p["Fc"]["value"] + sum(weights.values()) == pytest.approx(20.0, rel=0.05)
    # with no creeping rows (the creep speed at the standstill speed) the same data hold far
    # less evidence: only the few moving rows within the elastic range after each reversal
    moving_only = run_loop(est, val, LoopConfig(creep_fraction=0.01, **only))
    t_moving = next(s for s in moving_only.steps if s.effect == "presliding_hysteresis").evidence["t_heldout"]
    assert t_moving < 0.2 * step.evidence["t_heldout"]


@pytest.mark.parametrize("fs", [250.0, 1000.0, 5000.0])
def test_compliance_grid_keeps_a_sharp_resonance_within_half_its_bandwidth(fs):
    """At each physical damping ratio the frequency grid steps by at most ``zeta`` (relative, at
    least 3 %), so any resonance in the band lies within half its bandwidth of a grid point."""
    t = np.arange(0.0, 6.0, 1.0 / fs)
    q = 0.05 * np.sin(2 * np.pi * 0.5 * t)
    s = Signals(AxisData(t, q, 10.0 * np.sign(np.cos(2 * np.pi * 0.5 * t)), source="sine"))
    grid: dict[float, list[float]] = {}
    for m in _compliance_variants(LinearModel([]), s, np.zeros(s.n_rows)):
        fn, zeta = next(tm.hyper for tm in m.terms)
        grid.setdefault(zeta, []).append(fn)
    for zeta in COMPLIANCE_GRID_ZETAS:
        fns = np.sort(grid[zeta])
        assert fns[0] <= 2.0 + 1e-9 and fns[-1] >= resonance_limit(s) * (1 - 1e-9)
        assert np.max(fns[1:] / fns[:-1]) <= 1.0 + max(zeta, 0.03) + 1e-9


def _clean_rig_with(extra) -> tuple[AxisData, Rig]:
    """A clean rig's run with a force ``extra(t, qd, v_scale)`` added to its measured force."""
    rig = Rig(seed=4, fs=1000.0, duration=16.0)
    d = simulate_rig(rig)
    qd = np.gradient(d.position, d.t)
    v = float(np.percentile(np.abs(qd), 99))
    return AxisData(d.t, d.position, d.force + extra(d.t, qd, v), source="planted"), rig


def _chosen(eff, data: AxisData):
    """The variant of ``eff`` the loop's first round chooses on ``data`` (held-out blocks inside)."""
    from gmsfric.loop.select import _best_variant, _cv, _residual_rows, stage_baseline, stage_prepare

    cfg = LoopConfig(progress=False)
    split, chunk = stage_prepare(data, None, cfg)
    st = stage_baseline(split, chunk, cfg)
    _, r_est = _residual_rows(st, cfg)
    m, _ = _best_variant(eff, st.model, st, cfg, r_est)
    return m, (None if m is None else _cv(m, st.split, cfg)), st


def test_a_stribeck_curve_between_the_grid_widths_is_refined_to_its_own():
    """The grid's widths are a factor ~1.4 apart; a large hump fits far worse between them than at
    its own width, so the best grid curve is refined (width and exponent) before it meets the
    drag probes, which have no width to miss."""
    probe, _ = _clean_rig_with(lambda t, qd, v: 0.0 * t)
    s = Signals(probe)
    widths = sorted({tm.hyper[0] for m in CATALOGUE["stribeck"].variants(LinearModel([]), s, np.zeros(s.n_rows))
                     for tm in m.terms if tm.hyper[0] <= 0.5 * s.v_scale})
    vs = float(np.sqrt(widths[-4] * widths[-3]))  # half-way between two grid widths (log scale)
    fc = Rig().fc
    data, _ = _clean_rig_with(lambda t, qd, v: 1.2 * fc * np.sign(qd) * np.exp(-(np.abs(qd) / vs) ** 1.5))
    m, cv, _ = _chosen(CATALOGUE["stribeck"], data)
    assert m is not None
    got_vs, got_delta = next(tm.hyper for tm in m.terms if tm.name == "stribeck")
    assert got_vs == pytest.approx(vs, rel=0.1) and got_delta == pytest.approx(1.5, abs=0.2)
    assert m.params()["Fs_minus_Fc"]["value"] == pytest.approx(1.2 * fc, rel=0.1)
    # the grid alone lands a whole grid step off, with a clearly larger cross-validated error
    m_grid, cv_grid, _ = _chosen(replace(CATALOGUE["stribeck"], refine=None), data)
    assert m_grid is not None and cv < 0.8 * cv_grid


def test_a_drift_is_evaluated_on_the_estimation_runs_time_scale():
    """A warm-up's time constant and a trend's slope are the axis', in seconds: on a held-out run
    twice as long the drift columns follow the estimation run's time scale, as the axis model
    the loop writes does (it saves them in seconds), not one stretched to the held-out run."""
    def run(duration: float) -> Signals:
        t = np.arange(0.0, duration, 1e-3)
        q = 0.05 * np.sin(2 * np.pi * 0.5 * t)
        return Signals(AxisData(t, q, 10.0 * np.sign(np.cos(2 * np.pi * 0.5 * t)), source=f"{duration} s"))

    est, val = run(10.0), run(20.0)
    for m in CATALOGUE["friction_drift"].variants(LinearModel([]), est, np.zeros(est.n_rows)):
        term = next(tm for tm in m.terms if tm.name == "friction_drift")
        frac = term.hyper[0]
        h = (val.t / est.duration - 0.5) if frac == 0 else np.exp(-val.t / (frac * est.duration))
        np.testing.assert_allclose(term.full(val)[:, 0], np.sign(val.qd) * h, rtol=1e-12, atol=1e-15)


def test_a_warm_up_between_the_grid_time_constants_is_refined_to_its_own():
    tau = float(np.sqrt(0.15 * 0.4))  # of the run's duration, half-way between two grid points
    fc = Rig().fc
    data, rig = _clean_rig_with(lambda t, qd, v: 0.5 * fc * np.sign(qd) * np.exp(-t / (tau * t[-1])))
    m, _, st = _chosen(CATALOGUE["friction_drift"], data)
    assert m is not None
    got = next(tm.hyper[0] for tm in m.terms if tm.name == "friction_drift")
    assert got * st.split.est.duration == pytest.approx(tau * data.t[-1], rel=0.15)


def _gravity_joint(amplitude_rad: float):
    """A rotary joint moved at random over about ``2 amplitude_rad`` with gravity
    ``1.1 sin(q + 3.2)`` N m, Coulomb friction and a small viscous term; the baseline fitted to it
    and its residual."""
    from scipy import signal

    from gmsfric.loop.idim import fit_baseline

    rng = np.random.default_rng(4)
    fs = 500.0
    t = np.arange(int(30 * fs)) / fs
    b, a = signal.butter(2, 0.3 / (fs / 2))
    q = signal.filtfilt(b, a, rng.standard_normal(t.size))
    q = amplitude_rad * q / np.abs(q).max() + 1.0
    qd = np.gradient(q, t)
    f = 0.02 * np.gradient(qd, t) + 0.01 * qd + 1.4 * np.tanh(qd / 0.01) + 1.1 * np.sin(q + 3.2) + 0.01 * rng.standard_normal(t.size)
    s = Signals(AxisData(t, np.round(q / 1e-5) * 1e-5, f, rotary=True, source="joint"))
    base = fit_baseline(s)
    return s, base, s.y - base.predict(s)


def test_a_gravity_period_is_fitted_with_the_model_not_read_off_its_residual():
    """Gravity over about 2.1 turns: the baseline has already taken the sine's mean (offset) and
    odd part (Coulomb level), so the period read off its residual's periodogram is 19 % off
    2 pi; fitted with the model's own columns it is within 1 %."""
    from gmsfric.loop.effects import fitted_period, position_periods

    s, base, r = _gravity_joint(12.0)
    read = min(position_periods(s, r, False), key=lambda p: abs(p - 2 * np.pi))
    fitted = fitted_period(base, s, r, read, False)
    assert abs(read / (2 * np.pi) - 1.0) > 0.05
    assert abs(fitted / (2 * np.pi) - 1.0) < 0.01


def test_a_fitted_period_is_not_stretched_beyond_the_travel():
    """Gravity over 0.7 turn is, over that travel, a trend for the Legendre basis.  Started from
    a period of 0.95 travels (what the periodogram's refinement can return near its lowest
    frequency), the fit with the model's columns may not lengthen it beyond the travel; left
    free within half a periodogram bin it goes to 1.3 travels, which on a real EMPS run made a
    sine stand in for a trend."""
    from gmsfric.loop.effects import fitted_period

    s, base, r = _gravity_joint(4.0)
    travel = float(np.ptp(s.q))
    for odd in (False, True):
        assert fitted_period(base, s, r, 0.95 * travel, odd) <= travel * (1 + 1e-9)


def test_the_tone_rival_of_a_resonance_is_at_the_residuals_periodogram_peak():
    """A residual holding a sine of 6.13 Hz in time, with gaps where rows are left out: the tone
    rivals of a resonance chosen at 6.0 Hz sit on the peak, within the grid step (an eighth of
    the run's frequency resolution), and a resonance far from it gets no rival there."""
    from gmsfric.loop.effects import tone_rivals
    from gmsfric.loop.idim import LinearModel, Term

    rng = np.random.default_rng(3)
    t = np.arange(0.0, 20.0, 1e-3)
    data = AxisData(t, 0.01 * np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.5 * t), source="tone")
    s = Signals(data)
    rt = s.rows["t"]
    r = np.sin(2 * np.pi * 6.13 * rt + 0.4) + 0.5 * rng.standard_normal(rt.size)
    r[(rt % 2.0) < 0.3] = np.nan  # rows left out (standstill)
    base = LinearModel([], [])

    def chosen(fn):
        m = base.copy()
        m.terms = [Term("compliance", ("m_load",), lambda s, h: s.qdd, (fn, 0.05), ("fn_hz", "zeta"))]
        return m

    freqs = [m.terms[-1].hyper[0] for m, _ in tone_rivals(base, chosen(6.0), s, r)]
    step = 1.0 / (8.0 * np.ptp(rt))
    assert len(freqs) == 5 and abs(np.median(freqs) - 6.13) <= step
    far = [m.terms[-1].hyper[0] for m, _ in tone_rivals(base, chosen(12.0), s, r)]
    assert all(abs(f - 6.13) > 1.0 for f in far)


def _heating_runs(seed: int, strength: float = 1.0) -> tuple[AxisData, AxisData]:
    """A rig whose friction falls as it warms with the motion (the core's heating, 3 s memory):
    an estimation run at a steady pace, over which the warm-up is a drift in time, and a held-out
    run whose pace alternates between brisk and gentle phases."""
    from gmsfric.axis import AxisModel, Effects, Heating
    from gmsfric.loop.rigs import _trajectory
    from gmsfric.models import StaticFriction, Stribeck
    from gmsfric.system import Plant

    runs = []
    for s, steady in ((seed, True), (seed + 1000, False)):
        rig = Rig(effect="heating", seed=s, fs=1000.0, duration=24.0)
        rng = np.random.default_rng(s)
        ref = _trajectory(rig, rng)
        t = np.arange(ref.size) / rig.fs
        if not steady:
            ref = ref[0] + (ref - ref[0]) * (0.3 + 0.7 * np.sin(np.pi * t / (0.4 * rig.duration)) ** 2)
        v_typ = 0.1 * rig.travel / 0.15
        axis = AxisModel(Plant.from_mass(rig.mass, force_gain=rig.gain), StaticFriction(Stribeck(rig.fc, rig.fc, 1.0), sigma=rig.fv, offset=rig.offset),
                         Effects(heating=Heating(tau=3.0, d_level=-0.5 * strength * rig.fc / v_typ, d_viscous=-0.3 * strength * rig.fv / v_typ)))
        res = axis.simulate(1.0 / rig.fs, reference=ref, controller=rig.controller(), quantization=rig.quantization)
        assert res.command is not None
        runs.append(AxisData(res.t, res.measured, rig.gain * res.command + rng.normal(0.0, rig.force_noise, ref.size), source=f"heating, seed {s}"))
    return runs[0], runs[1]


def _with_drift_accepted(est: AxisData, val: AxisData, cfg: LoopConfig):
    """The loop's state after a selection that could only name a friction drift."""
    from gmsfric.loop.select import stage_baseline, stage_prepare, stage_select

    split, chunk = stage_prepare(est, val, cfg)
    st = stage_baseline(split, chunk, cfg)
    stage_select(st, cfg, ["friction_drift"])
    assert st.model.effects == ["friction_drift"]
    return st


def test_the_other_form_of_a_drift_replaces_it_only_where_it_predicts_the_held_out_run_better():
    """Heating and a drift in time are two forms of one phenomenon: once a drift is in the model,
    heating is tried in its place at the nominal level (it names nothing new) and judged against
    the drift on the held-out run, while any other effect tried in the drift's place takes the
    family's share of the level.  On a heating rig whose held-out run changes pace (over a steady
    estimation run, a drift in time enters first), heating replaces the drift; on a drift rig,
    the drift stays."""
    from gmsfric._progress import Progress
    from gmsfric.loop.effects import alternative_forms
    from gmsfric.loop.heldout import clear_rows
    from gmsfric.loop.select import _exchange_step, _residual_rows

    assert alternative_forms("heating", "friction_drift") and alternative_forms("friction_drift", "heating")
    assert not alternative_forms("friction_drift", "stribeck")
    names = ["friction_drift", "heating", "asymmetric_friction"]
    cfg = LoopConfig(progress=False, effects=tuple(names))
    drift = Rig(effect="friction_drift", seed=2, fs=1000.0, duration=24.0)
    for runs, replaced in ((_heating_runs(2), True), ((simulate_rig(drift), simulate_rig(replace(drift, seed=1002))), False)):
        st = _with_drift_accepted(*runs, cfg)
        fnd, _ = _residual_rows(st, cfg)
        made = _exchange_step(st, cfg, 3, names, clear_rows(st.split), fnd, Progress("test", enabled=False))
        trial = next(s for s in st.steps if s.effect == "heating" and s.evidence.get("replaces") == "friction_drift")
        assert trial.evidence["other_form_of"] == "friction_drift" and trial.evidence["level"] == cfg.alpha
        # an effect that is no form of the drift takes the family's share of the level
        other = next(s for s in st.steps if s.effect == "asymmetric_friction" and s.evidence.get("replaces") == "friction_drift")
        assert "other_form_of" not in other.evidence and other.evidence["level"] < cfg.alpha / 4
        assert made is replaced and trial.accepted is replaced
        assert st.model.effects == (["heating"] if replaced else ["friction_drift"])
