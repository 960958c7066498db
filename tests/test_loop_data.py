"""Data loading for `gmsfric loop`: explicit columns, units, clear errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.io import savemat

from gmsfric.errors import DataError, InvalidInputError
from gmsfric.loop import AxisData, load_axis_data, run_loop
from gmsfric.units import UnitError


def _csv(path, cols: dict[str, np.ndarray]) -> str:
    names = list(cols)
    rows = np.column_stack([cols[n] for n in names])
    np.savetxt(path, rows, delimiter=",", header=",".join(names), comments="")
    return str(path)


def _run(n: int = 500):
    t = np.arange(n) * 1e-3
    q = 0.01 * np.sin(2 * np.pi * t)
    return t, q, 3.0 * np.cos(2 * np.pi * t)


def test_csv_with_force_and_units(tmp_path):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"time_ms": t * 1e3, "pos_mm": q * 1e3, "F": f})
    d = load_axis_data(p, time="time_ms", position="pos_mm", force="F", time_unit="ms", position_unit="mm")
    assert d.dt == pytest.approx(1e-3)
    np.testing.assert_allclose(d.position, q, atol=1e-12)
    np.testing.assert_allclose(d.force, f)
    assert d.gain is None


def test_mat_with_command_and_gain_by_name_or_number(tmp_path):
    t, q, f = _run()
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:, None], "vir": (f / 2.5)[:, None], "gtau": np.array([[2.5]])})
    d1 = load_axis_data(p, time="t", position="qm", command="vir", gain="gtau")
    d2 = load_axis_data(p, time="t", position="qm", command="vir", gain=2.5)
    np.testing.assert_allclose(d1.force, f)
    np.testing.assert_allclose(d2.force, f)
    assert d1.gain == 2.5


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(force="nope"), "unknown force column 'nope'"),
        (dict(command="F"), "needs a drive gain"),
        (dict(command="F", gain="missing"), "'missing' is neither a number nor a scalar"),
        (dict(force="F", command="F", gain=1.0), "either a force column or a command column"),
        (dict(), "either a force column or a command column"),
    ],
)
def test_bad_column_specs(tmp_path, kwargs, message):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match=message):
        load_axis_data(p, time="t", position="q", **kwargs)


def test_mismatched_lengths(tmp_path):
    t, q, f = _run()
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:-3, None], "F": f[:, None]})
    with pytest.raises(DataError, match="different lengths"):
        load_axis_data(p, time="t", position="qm", force="F")


def test_nan_named(tmp_path):
    t, q, f = _run()
    f[123] = np.nan
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:, None], "F": f[:, None]})
    with pytest.raises(DataError, match="non-finite value at row 123"):
        load_axis_data(p, time="t", position="qm", force="F")


def test_non_monotonic_time(tmp_path):
    t, q, f = _run()
    t[200] = t[198]
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match="not strictly increasing at row 200"):
        load_axis_data(p, time="t", position="q", force="F")


def test_a_few_repeated_time_stamps_are_merged_and_a_coarse_time_column_is_refused(tmp_path):
    t, q, f = _run(2000)
    stamped = t.copy()
    late = [300, 301, 900, 1500, 1777]
    stamped[late] = stamped[np.array(late) - 1]  # a logger stamping a late sample like the one before
    stamped[301] = stamped[299]
    d = load_axis_data(_csv(tmp_path / "run.csv", {"t": stamped, "q": q, "F": f}), time="t", position="q", force="F")
    assert d.timing["repeated_stamps_merged"] == 5 and d.timing["samples_in"] == 2000 and d.timing["resampled"]
    np.testing.assert_allclose(np.diff(d.t), 1e-3, rtol=1e-9)
    # a merged sample is the mean of its samples at the earlier stamp: off by at most a step's change
    np.testing.assert_allclose(d.force, 3.0 * np.cos(2 * np.pi * d.t), atol=3.0 * 2 * np.pi * 2e-3)
    # a 2 kHz log stamped in whole milliseconds repeats every other stamp
    t2 = np.round(np.arange(2000) * 0.5e-3, 3)
    with pytest.raises(DataError, match="not strictly increasing at row 1: 999 of 2000 time stamps repeat.*rounded too coarsely"):
        load_axis_data(_csv(tmp_path / "coarse.csv", {"t": t2, "q": 0.01 * np.sin(2 * np.pi * t2), "F": f}), time="t", position="q", force="F")


def test_magnitudes_a_fit_cannot_square_are_refused_and_large_physical_ones_are_not():
    t, q, f = _run()
    with pytest.raises(DataError, match=r"force reaches 3e\+200.*check its unit"):
        AxisData(t, q, f * 1e200)
    # nanometre counts of a metre of travel, a micro-second log: far from the limit, accepted
    data = AxisData(t * 1e-3, q * 1e9, f)
    assert np.isfinite(data.position).all() and data.position.max() > 1e6


def test_too_few_samples(tmp_path):
    t, q, f = _run(50)
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match="too few samples"):
        load_axis_data(p, time="t", position="q", force="F")


def test_unknown_unit(tmp_path):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(UnitError, match="`position_unit`.*unknown unit 'furlong'"):
        load_axis_data(p, time="t", position="q", force="F", position_unit="furlong")


def test_jittered_log_is_resampled_not_refused(tmp_path):
    """A robot log that is late now and then (steps 2-18 ms around 10 ms) is put on a uniform
    grid at its median step; the jitter is measured and reported, the signals interpolated."""
    rng = np.random.default_rng(3)
    k = np.arange(3000)
    late = np.where(rng.random(k.size) < 0.15, rng.uniform(0.002, 0.008, k.size), 0.0)
    t = k * 0.01 + late
    q = 0.3 * np.sin(2 * np.pi * 0.2 * t)
    f = 2.0 * np.cos(2 * np.pi * 0.2 * t)
    p = _csv(tmp_path / "robot.csv", {"t": t, "q": q, "tau": f})
    d = load_axis_data(p, time="t", position="q", force="tau", position_unit="rad", force_unit="N m")
    tm = d.timing
    assert tm["irregular"] and tm["resampled"]
    assert tm["median_step_s"] == pytest.approx(0.01, rel=1e-6)
    assert tm["min_step_s"] < 0.005 and tm["max_step_s"] > 0.015 and 5.0 < tm["irregular_steps_pct"] < 40.0
    np.testing.assert_allclose(np.diff(d.t), 0.01, rtol=1e-9)
    assert d.t[0] == t[0] and d.t[-1] <= t[-1] and tm["samples_out"] == d.t.size
    # linear interpolation of a smooth signal sampled at 100 Hz: errors of order (w dt)^2 / 8
    np.testing.assert_allclose(d.position, 0.3 * np.sin(2 * np.pi * 0.2 * d.t), atol=0.3 * (2 * np.pi * 0.2 * 0.02) ** 2)
    np.testing.assert_allclose(d.force, 2.0 * np.cos(2 * np.pi * 0.2 * d.t), atol=2.0 * (2 * np.pi * 0.2 * 0.02) ** 2)
    assert d.rotary


def test_a_resampled_log_keeps_the_encoder_step_as_its_resolution():
    """Interpolating a quantised position onto a uniform grid puts values between the encoder's
    steps: the resolution (which bounds pre-sliding blocks, the switch at reversals and the
    standstill test) is the step as logged, not the smallest change after the resampling."""
    from gmsfric.loop import AxisData, Signals
    from gmsfric.loop.data import quantisation_step

    rng = np.random.default_rng(5)
    k = np.arange(4000)
    t = k * 0.01 + np.where(rng.random(k.size) < 0.3, rng.uniform(0.001, 0.008, k.size), 0.0)
    step = 5e-5
    q = step * np.round(0.02 * np.sin(2 * np.pi * 0.1 * t) / step)  # a few steps per sample
    f = 3.0 * np.cos(2 * np.pi * 0.1 * t) + 0.5 * np.sign(np.cos(2 * np.pi * 0.1 * t))
    d = AxisData(t, q, f, rotary=True)
    assert d.timing["resampled"]
    assert d.timing["position_step_as_logged"] == pytest.approx(step, rel=1e-6)
    assert quantisation_step(d.position) < 0.5 * step  # what the resampled log alone would say
    assert Signals(d).resolution == pytest.approx(step, rel=1e-6)
    # a logged step that is no length within the travel (hand-made timing) is not trusted
    for bad in (float("nan"), -1.0, 1e300, "50 um"):
        odd = AxisData(d.t, d.position, d.force, rotary=True, timing={**d.timing, "position_step_as_logged": bad})
        assert Signals(odd).resolution == pytest.approx(Signals(AxisData(d.t, d.position, d.force, rotary=True, timing={"irregular": False})).resolution)
    uniform = AxisData(k * 0.01, step * np.round(0.02 * np.sin(2 * np.pi * 0.1 * k * 0.01) / step), f)
    assert "position_step_as_logged" not in uniform.timing and Signals(uniform).resolution == pytest.approx(step, rel=1e-6)


def _fast_moves_with_stops(step: float, fs: float = 1000.0) -> tuple[np.ndarray, np.ndarray]:
    """Moves of 0.1 m at up to 0.2 m/s with rests between them, where the axis creeps a few steps,
    quantised to ``step``: one step per sample happens only near a stop, so few changes are as
    small as the step."""
    t = np.arange(0.0, 20.0, 1.0 / fs)
    phase = np.mod(t, 2.0)
    ramp = np.clip(phase / 1.0, 0.0, 1.0)  # move for 1 s, rest for 1 s
    smooth = ramp * ramp * (3.0 - 2.0 * ramp)
    direction = np.where(np.mod(np.floor(t / 2.0), 2.0) == 0.0, 1.0, -1.0)
    base = np.where(direction > 0, 0.0, 0.1)
    creep = np.where(phase > 1.0, 3.0 * step * np.sin(np.pi * (phase - 1.0)), 0.0)
    q = base + direction * 0.1 * smooth + creep
    return t, step * np.round(q / step)


def test_the_encoder_step_is_read_off_the_lattice_a_log_rests_on():
    """A fast log of fast moves changes by a single step only next to stops, so the 1st
    percentile of its changes is many steps; the lattice it rests on gives the step, and it is the
    narrowest pre-sliding block the loop tries, while what counts as standstill is unchanged."""
    from gmsfric.loop import AxisData, Signals
    from gmsfric.loop.data import encoder_step, quantisation_step

    step = 5e-8
    t, q = _fast_moves_with_stops(step)
    assert quantisation_step(q) > 5 * step
    assert encoder_step(q) == pytest.approx(step, rel=1e-6)
    s = Signals(AxisData(t, q, np.sin(t) + 2.0))
    assert s.contact_resolution == pytest.approx(step, rel=1e-6)
    assert s.resolution == pytest.approx(quantisation_step(q), rel=1e-6)
    # written with few digits (a step of 53.3 nm in mm to six decimals): the lattice within 10 %
    rounded = np.round(_fast_moves_with_stops(5.33e-8)[1] * 1e3, 6) * 1e-3
    assert encoder_step(rounded) == pytest.approx(5.33e-8, rel=0.05)


def test_a_log_stored_more_finely_than_its_sensor_has_no_encoder_step():
    """A position that never stands still, stored to 50 nm (the real EMPS estimation run changes by
    multiples of 0.05 um and rests between 1 of 25 000 samples), sits on its storage's lattice: that
    says nothing about the sensor, and the contact resolution stays the resolution."""
    from gmsfric.loop import AxisData, Signals
    from gmsfric.loop.data import encoder_step

    rng = np.random.default_rng(3)
    t, q = _fast_moves_with_stops(1e-12)
    noisy = 5e-8 * np.round((q + 2e-5 * rng.standard_normal(t.size)) / 5e-8)
    assert 0.0 < np.mean(np.diff(noisy) == 0.0) < 1e-3  # it rests between a few samples
    assert encoder_step(noisy) is None
    s = Signals(AxisData(t, noisy, np.sin(t) + 2.0))
    assert s.contact_resolution == s.resolution
    # a few odd changes of a quarter step (glitches) are not the step: fewer than ten single ones
    step = 2e-7
    coarse = step * np.round(_fast_moves_with_stops(1e-12)[1] / step)
    coarse[[5000, 9000, 13000]] += step / 4
    assert encoder_step(coarse) is None


def test_a_resampled_log_keeps_the_lattice_it_rested_on():
    """Interpolating onto a uniform grid puts positions between steps: the step is read before,
    and the contact resolution is that step or the position noise the late stamps leave."""
    from gmsfric.loop import AxisData, Signals
    from gmsfric.loop.idim import position_noise

    step = 5e-8
    t, q = _fast_moves_with_stops(step)
    rng = np.random.default_rng(7)
    late = t + np.where(rng.random(t.size) < 0.3, rng.uniform(1e-4, 8e-4, t.size), 0.0)
    d = AxisData(late, q, np.sin(late) + 2.0)
    assert d.timing["resampled"] and d.timing["encoder_step_as_logged"] == pytest.approx(step, rel=1e-6)
    s = Signals(d)
    assert s.contact_resolution == pytest.approx(max(step, position_noise(d.position, s.q)), rel=1e-9)
    assert s.contact_resolution < 0.5 * s.resolution
    # a logged step that is no length within the travel (hand-made timing) is not trusted
    for bad in (float("nan"), -1.0, 1e300, "50 nm"):
        odd = AxisData(d.t, d.position, d.force, timing={**d.timing, "encoder_step_as_logged": bad})
        assert Signals(odd).contact_resolution == Signals(odd).resolution


def test_uniform_log_is_left_alone(tmp_path):
    t, q, f = _run()
    t = t + 1e-9 * np.random.default_rng(0).standard_normal(t.size)  # rounding in a text file
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    d = load_axis_data(p, time="t", position="q", force="F")
    assert not d.timing["irregular"] and not d.timing["resampled"]
    np.testing.assert_array_equal(d.position, q)


@pytest.mark.parametrize("fs", [200.0, 1000.0, 5000.0])
def test_decimated_rows_keep_positions_and_times_as_values(fs):
    # Rows are what the residual is analysed on (profiles along the travel, periods in time): a
    # decimated position or time stamp must equal the full-rate one at the same instant, not come
    # out scaled by the anti-alias filter's gain (1.15 % short would shift a 50-period cogging
    # profile by half a period across the travel).
    from gmsfric.loop import AxisData, Signals

    t = np.arange(0.0, 20.0, 1.0 / fs)
    q = 0.2 * np.sin(2 * np.pi * 0.1 * t) + 0.01 * t
    s = Signals(AxisData(t, q, np.cos(t), source="ramp"))
    assert s.dec > 1
    at = slice(s.edge, t.size - s.edge, s.dec)
    inner = slice(20, -20)  # away from the filter's start-up at both ends
    np.testing.assert_allclose(s.rows["t"][inner], (t - t[0])[at][: s.n_rows][inner], rtol=0, atol=1e-4)
    np.testing.assert_allclose(s.rows["q"][inner], s.q[at][: s.n_rows][inner], rtol=0, atol=1e-4 * np.ptp(q))


@pytest.mark.parametrize("fs", [1000.0, 5000.0])
def test_a_force_step_rings_over_the_decimation_settling_rows(fs):
    # A force step the regressors do not share (stiction crossed while the axis holds) leaks into
    # the rows around it through the anti-alias filter; rows farther than the settling count are
    # within 1 % of the step, and the ringing does reach that far (the count is not padding).
    from gmsfric.loop import AxisData, Signals
    from gmsfric.loop.idim import DECIMATION_SETTLING_TOL, decimation_settling_rows

    t = np.arange(0.0, 4.0, 1.0 / fs)
    t_step = 2.0
    s = Signals(AxisData(t, 0.01 * np.sin(t), (t >= t_step).astype(float), source="step"))
    n = decimation_settling_rows(s.dec)
    assert s.dec > 1 and 5 <= n <= 10  # tens of milliseconds at 100 Hz rows
    k = np.arange(s.n_rows)
    i_step = int(np.argmin(np.abs(s.rows["t"] - t_step)))
    off = np.abs(s.y - (k >= i_step))
    assert off[np.abs(k - i_step) > n + 1].max() <= DECIMATION_SETTLING_TOL
    assert off[np.abs(k - i_step) >= n - 1].max() > 0.5 * DECIMATION_SETTLING_TOL


@pytest.mark.parametrize("kwargs, message", [
    (dict(cutoff_hz=float("nan")), "cutoff_hz"),
    (dict(cutoff_hz=-1.0), "cutoff_hz"),
    (dict(cutoff_hz=1e-9), "fewer than 10 of its periods"),  # its windows would not fit in memory
    (dict(order=0), "order"),
    (dict(decimation=2.5), "decimation"),
    (dict(edge_s=float("inf")), "edge_s"),
])
def test_bad_preprocessing_is_refused_by_name_before_any_work(kwargs, message):
    from gmsfric.errors import InvalidInputError
    from gmsfric.loop import AxisData, Preprocessing, Signals

    t = np.arange(0.0, 10.0, 1e-3)
    with pytest.raises(InvalidInputError, match=message):
        Signals(AxisData(t, 0.05 * np.sin(t), np.cos(t), source="run"), Preprocessing(**kwargs))


@pytest.mark.parametrize("fs, want", [
    (100.0, [10.0, 20.0, 30.0]),
    (250.0, [25.0, 50.0, 75.0]),
    (500.0, [50.0, 100.0]),
    (999.9, [99.99]),  # a 1 kHz log whose clock runs a little fast: the recipe alone
    (1000.0, [100.0]),
    (5000.0, [100.0]),
])
def test_cut_offs_to_choose_from_widen_only_below_1_khz(fs, want):
    from gmsfric.loop import Preprocessing

    assert Preprocessing().cutoffs(fs) == pytest.approx(want)
    assert Preprocessing(cutoff_hz=30.0).cutoffs(fs) == [30.0]  # a given cut-off is kept


@pytest.mark.parametrize("fs", [float("nan"), 0.0, -100.0, "100"])
def test_cut_offs_refuse_a_bad_sample_rate_by_name(fs):
    from gmsfric.errors import InvalidInputError
    from gmsfric.loop import Preprocessing

    with pytest.raises(InvalidInputError, match="`fs`"):
        Preprocessing().cutoffs(fs)


def test_too_few_moving_rows_keep_the_recipes_cut_off():
    from gmsfric.loop import AxisData, LoopConfig
    from gmsfric.loop.select import MIN_ROWS_TO_CHOOSE_CUTOFF, make_split

    t = np.arange(0.0, 3.0, 0.01)  # 100 Hz, moving for 0.4 s only
    q = np.where(t < 0.4, 0.01 * np.sin(np.pi * t / 0.4) ** 2, 0.0)
    split = make_split(AxisData(t, q, np.cos(t), source="short"), None, LoopConfig(progress=False))
    assert split.preprocessing["chosen_by"].startswith("the recipe (fewer than")
    assert split.preprocessing["cutoff_hz"] == pytest.approx(10.0) and split.est_fit.sum() < MIN_ROWS_TO_CHOOSE_CUTOFF


_T, _Q, _F = _run()


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda: AxisData(None, _Q, _F), "`t` is missing"),
        (lambda: AxisData(_T[:, None], _Q, _F), "`t` must be one-dimensional"),
        (lambda: AxisData(np.r_[_T[:7], np.nan, _T[8:]], _Q, _F), "t has a non-finite value at row 7"),
        (lambda: AxisData(_T, ["a"] * _T.size, _F), "`position` must be numeric"),
        (lambda: AxisData(_T, _Q, _F, command=_F, gain=float("nan")), "`gain` must be finite and non-zero"),
        (lambda: AxisData(_T, _Q, _F, command=_F, gain=0.0), "`gain` must be finite and non-zero"),
        (lambda: AxisData(_T, _Q, _F, rotary="yes"), "`rotary` must be True or False"),
        (lambda: run_loop("run.csv"), "`est` must be an AxisData"),
        (lambda: run_loop(AxisData(_T, _Q, _F), _T), "`val` must be an AxisData"),
    ],
)
def test_the_python_entry_points_name_a_bad_argument(make, match):
    with pytest.raises(InvalidInputError, match=match) as info:
        make()
    assert isinstance(info.value, ValueError)


def test_plain_lists_are_accepted_as_columns():
    data = AxisData(list(_T), list(_Q), list(_F))
    assert data.position.dtype == np.float64 and data.dt == pytest.approx(1e-3)


@pytest.mark.parametrize("dec", [2, 5, 10, 13])
def test_the_loop_decimates_as_scipy_does(dec):
    from scipy import signal

    from gmsfric.loop.idim import zero_phase_decimate

    x = np.random.default_rng(dec).standard_normal((40 * dec + 7, 3)).cumsum(axis=0)
    expected = signal.decimate(x, dec, axis=0, zero_phase=True)
    got = zero_phase_decimate(x, dec)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def test_a_log_without_time_takes_a_sample_rate_and_refuses_a_bad_one(tmp_path):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    timed = load_axis_data(p, time="t", position="q", force="F")
    untimed = load_axis_data(p, sample_rate=1000.0, position="q", force="F")
    np.testing.assert_allclose(untimed.t, timed.t, atol=1e-12)
    with pytest.raises(DataError, match=r"either a time column \(`time`\) or a sample rate"):
        load_axis_data(p, time="t", sample_rate=1000.0, position="q", force="F")
    with pytest.raises(DataError, match=r"either a time column \(`time`\) or a sample rate"):
        load_axis_data(p, position="q", force="F")
    for bad in (0.0, -5.0, float("nan"), "1000"):
        with pytest.raises(InvalidInputError, match="`sample_rate`"):
            load_axis_data(p, sample_rate=bad, position="q", force="F")


def test_a_gap_in_the_log_is_marked_unobserved_not_made_up():
    """A logger that loses 0.3 s of a 1 kHz log: the uniform grid runs through the gap, but its
    samples there are interpolated, so they are marked unobserved, and the loop's rows within
    the filters' reach of them are left out; a late sample now and then is no gap."""
    from gmsfric.loop import Signals
    from gmsfric.loop.data import GAP_STEPS

    t = np.arange(6000) * 1e-3
    keep = (t < 2.5) | (t > 2.8)
    q = 0.02 * np.sin(2 * np.pi * 0.5 * t)
    f = 5.0 * np.cos(2 * np.pi * 0.5 * t) + np.sign(np.cos(2 * np.pi * 0.5 * t))
    d = AxisData(t[keep], q[keep], f[keep])
    tm = d.timing
    assert tm["resampled"] and tm["gaps"] == 1 and tm["longest_gap_s"] == pytest.approx(0.301, rel=1e-6)
    np.testing.assert_allclose(np.diff(d.t), 1e-3, rtol=1e-9)
    inside = (d.t > 2.5 - 1e-9) & (d.t < 2.801 - 1e-9) & ~np.isin(np.round(d.t * 1e3), np.round(t[keep] * 1e3))
    np.testing.assert_array_equal(d.observed, ~inside)
    assert tm["samples_in_gaps"] == int(inside.sum()) == 300
    s = Signals(d)
    gap_rows = (s.rows["t"] + d.t[0] > 2.5) & (s.rows["t"] + d.t[0] < 2.8)
    assert s.in_gap[gap_rows].all() and not s.moving[gap_rows].any()
    assert 0.0 < s.in_gap.mean() < 0.2  # the gap and the filters' reach, not the run
    assert not s.observed[inside].any() and s.observed[~inside].mean() > 0.9
    # a sample late by half a step now and then (steps of 1.5 steps) is jitter, not a gap
    late = t + np.where(np.arange(t.size) % 97 == 0, 0.5e-3, 0.0)
    jittered = AxisData(late, q, f)
    assert jittered.timing["resampled"] and jittered.timing["gaps"] == 0 and jittered.observed is None
    # a step just over GAP_STEPS median steps is one
    stretched = np.concatenate([t[:3000], t[3000:] + (GAP_STEPS - 0.9) * 1e-3])
    assert AxisData(stretched, q, f).timing["gaps"] == 1


def test_the_loop_leaves_a_gap_out_and_says_so():
    """Runs of a rig with a planted viscous asymmetry, each with two lost stretches of 0.25 s:
    interpolated across, the gaps' straight lines are forces no model explains and the loop
    named nothing; left out, it finds the asymmetry, the baseline stays the rig's, and the
    report says what was left out."""
    from gmsfric.loop.rigs import Rig, rig_pair

    rig = Rig(effect="asymmetric_friction", duration=16.0, seed=4)

    def with_gaps(d: AxisData) -> AxisData:
        keep = ~(((d.t > 5.0) & (d.t < 5.25)) | ((d.t > 11.0) & (d.t < 11.25)))
        return AxisData(d.t[keep], d.position[keep], d.force[keep], source=d.source)

    est, val = (with_gaps(d) for d in rig_pair(rig))
    with pytest.warns(Warning):
        res = run_loop(est, val)
    assert "asymmetric_friction" in res.final.effects
    p = res.final.params()
    assert p["M"]["value"] == pytest.approx(rig.mass, rel=0.05)
    assert p["Fc"]["value"] == pytest.approx(rig.fc, rel=0.15)
    gaps = [d for d in res.diagnostics if d["code"] == "data" and d["parameter"] == "time"]
    assert len(gaps) == 1 and "2 gaps" in gaps[0]["message"] and "left out" in gaps[0]["message"]
    # held-out blocks of the estimation run itself: neither the fitted nor the held-out rows hold a gap
    with pytest.warns(Warning):
        alone = run_loop(est)
    assert "asymmetric_friction" in alone.final.effects
    assert not (alone.split.est_rows & alone.split.est.in_gap).any() and not (alone.split.val_rows & alone.split.est.in_gap).any()
    assert alone.split.est.in_gap.any()


def _wrapped(a: np.ndarray) -> np.ndarray:
    """An angle as an encoder that keeps it within (-pi, pi] logs it."""
    return (a + np.pi) % (2 * np.pi) - np.pi


def test_a_rotary_angle_that_wraps_around_is_unwrapped_and_a_jump_that_is_no_turn_refused():
    t = np.arange(3000) * 1e-3
    q = np.pi - 0.05 + 0.3 * np.sin(2 * np.pi * 1.0 * t)  # crosses +pi, where the encoder wraps
    f = 2.0 * np.cos(2 * np.pi * 1.0 * t)
    d = AxisData(t, _wrapped(q), f, rotary=True)
    n_wraps = int((np.abs(np.diff(_wrapped(q))) > np.pi).sum())
    assert n_wraps >= 4 and d.timing["turns_unwrapped"] == n_wraps
    np.testing.assert_allclose(d.position, q - 2 * np.pi * np.round((q[0] - d.position[0]) / (2 * np.pi)), atol=1e-12)
    assert np.abs(np.diff(d.position)).max() < 0.01
    # a linear axis is never unwrapped: its position is in metres
    assert "turns_unwrapped" not in AxisData(t, 1e-3 * np.sin(t), f).timing
    # a jump of more than half a turn that is no whole turn is no encoder's wrap: refused, named
    bad = q.copy()
    bad[1500:] += 4.0
    with pytest.raises(DataError, match=r"position jumps by 3\.99.* rows 1499 and 1500.*not a whole turn"):
        AxisData(t, bad, f, rotary=True)


def test_the_held_out_run_is_put_on_the_turn_of_the_estimation_run_without_changing_it():
    from gmsfric.loop.data import on_the_same_turn

    t = np.arange(3000) * 1e-3
    f = 2.0 * np.cos(2 * np.pi * t)
    est = AxisData(t, _wrapped(np.pi - 0.05 + 0.3 * np.sin(2 * np.pi * t)), f, rotary=True)
    val = AxisData(t, _wrapped(np.pi + 0.2 + 0.3 * np.sin(2 * np.pi * 0.7 * t)), f, rotary=True)  # starts past pi: wrapped to -pi + 0.2
    kept = val.position.copy()
    moved = on_the_same_turn(est, val)
    assert moved is not val and moved.timing["turns_moved_onto_estimation_travel"] == 1
    np.testing.assert_allclose(moved.position, kept + 2 * np.pi)
    assert abs(np.median(moved.position) - np.median(est.position)) < 1.0
    np.testing.assert_array_equal(val.position, kept)  # the input is never changed
    assert on_the_same_turn(est, est) is est
    plain = AxisData(t, 0.3 * np.sin(2 * np.pi * t), f, rotary=True)
    assert on_the_same_turn(plain, AxisData(t, plain.position + 2 * np.pi, f, rotary=True)).position[0] == pytest.approx(2 * np.pi)


def test_the_loop_on_a_wrapped_rotary_log_finds_what_it_finds_on_the_unwrapped_one():
    """A rig's runs read as a joint's angle about +pi, where the encoder wraps: unwrapped and put
    on one turn, the loop finds the planted asymmetry with the same parameters as on the
    continuous angle, and says what it did; wrapped as logged, the velocity holds 2 pi jumps."""
    from gmsfric.loop.rigs import Rig, rig_pair

    runs = rig_pair(Rig(effect="asymmetric_friction", duration=16.0, seed=4))
    angle = [AxisData(d.t, np.pi - 0.05 + 5.0 * d.position, d.force, rotary=True, source=d.source) for d in runs]
    wrapped = [AxisData(d.t, _wrapped(d.position), d.force, rotary=True, source=d.source) for d in angle]
    assert all(w.timing["turns_unwrapped"] >= 1 for w in wrapped)
    with pytest.warns(Warning):
        res_w = run_loop(*wrapped)
    res_a = run_loop(*angle)
    assert res_w.final.effects == res_a.final.effects and "asymmetric_friction" in res_a.final.effects
    pw, pa = res_w.final.params(), res_a.final.params()
    for name in ("M", "Fv", "Fc"):
        assert pw[name]["value"] == pytest.approx(pa[name]["value"], rel=1e-6)
    assert any(d["code"] == "data" and d["parameter"] == "position" and "unwrapped" in d["message"] for d in res_w.diagnostics)


def test_a_force_of_the_opposite_sign_is_refused_not_fitted():
    """A force logged as the reaction on the axis (or a drive gain of the other sign): the
    baseline's inertia and Coulomb friction come out negative, which no effect explains, so the
    loop says what is wrong instead of returning a negative mass with a diagnostic."""
    from gmsfric.errors import IdentificationError
    from gmsfric.loop.rigs import Rig, rig_pair

    est, val = rig_pair(Rig(duration=8.0, seed=2))
    flipped = [AxisData(d.t, d.position, -d.force, source=d.source) for d in (est, val)]
    with pytest.raises(IdentificationError, match=r"opposite sign to the motion.*M = -6\d\.?\d* kg.*negate the force"):
        run_loop(*flipped)


def test_a_run_keeps_a_bounded_cache_of_columns_and_makes_the_evicted_again(monkeypatch):
    """The columns of every grid point of every effect, at the full rate, filled 5.6 GB on a log
    of half a million samples: a run keeps at most ``CACHE_BYTES`` of them, the least recently
    used go first, and one asked for again is made again, equal."""
    from gmsfric.loop import Signals, idim

    t, q, f = _run(4000)
    s = Signals(AxisData(t, q, f + np.sign(np.cos(2 * np.pi * t))))
    monkeypatch.setattr(idim, "CACHE_BYTES", 5 * 8 * 4000)  # five columns
    made: list[int] = []

    def column(k: int):
        def make():
            made.append(k)
            return np.full(4000, float(k))
        return s.cached(("test", k), make)

    for k in range(8):
        column(k)
    assert s._cache_bytes <= idim.CACHE_BYTES and len(made) == 8
    column(7)  # recent: kept
    assert len(made) == 8
    np.testing.assert_array_equal(column(0), np.zeros(4000))  # evicted: made again, equal
    assert made[-1] == 0 and s._cache_bytes <= idim.CACHE_BYTES


def test_the_loop_ends_the_same_with_a_cache_far_too_small_for_its_columns(monkeypatch):
    from gmsfric.loop import idim
    from gmsfric.loop.rigs import Rig, rig_pair

    est, val = rig_pair(Rig(effect="stribeck", duration=8.0, seed=3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        plenty = run_loop(est, val)
        monkeypatch.setattr(idim, "CACHE_BYTES", 2**21)  # about 30 of its columns, against thousands made
        starved = run_loop(est, val)
    assert starved.final.effects == plenty.final.effects
    np.testing.assert_allclose(starved.final.theta, plenty.final.theta, rtol=1e-12, atol=0)
    assert [s.reason for s in starved.steps] == [s.reason for s in plenty.steps]
    # the plentiful run held far more than the starved one could: the starved one evicted
    assert plenty.split.est._cache_bytes > 10 * 2**21 >= 10 * starved.split.est._cache_bytes


def test_a_log_that_is_mostly_gap_is_refused_before_its_grid_is_allocated():
    """Two stretches of a 1 kHz log 1e12 s apart (a clock that jumped): a uniform grid through
    the gap would hold 1e15 samples; refused naming the gap, not a MemoryError."""
    t = np.arange(3000) * 1e-3
    t[1500:] += 1e12
    with pytest.raises(DataError, match=r"mostly gaps \(the longest after row 1499, 1e\+12 s\)"):
        AxisData(t, 0.01 * np.sin(np.arange(3000) / 50), np.cos(np.arange(3000) / 50))
