"""The paper's Section 4.2 scenario, the circle test and friction feedforward (physics runs).

Coarse step (5e-4 s; the core's GMS update is exact at any step) and half a period (one
reversal) keep these fast; the metrics agree with the 1e-4 s full-period run to < 0.1 %.

"static" is the paper's static map as Simulink simulates it (linear region below 1e-4 m/s, it
cannot stick); "static_stiction" the same map with true stiction (docs/glitch.md).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from gmsfric import presets
from gmsfric.errors import InvalidInputError
from gmsfric.glitch import (
    DEFAULT_GAINS,
    PAPER_STATIC_V_LINEAR,
    compensation_sweep,
    friction_feedforward,
    plot_circle_polar,
    plot_compensation,
    plot_tracking_errors,
    run_circle,
    run_compensation,
    run_sinusoid,
    scenario_controller,
    sinusoid_reference,
)
from gmsfric.cli import main as gmsfric_main
from gmsfric.system import PIDDOB, simulate_closed_loop

FAST = dict(dt=5e-4, periods=0.5)


@pytest.fixture(scope="module")
def sinusoid():
    return run_sinusoid(**FAST)


@pytest.fixture(scope="module")
def compensation():
    return run_compensation(**FAST)


def test_friction_makes_glitches_and_none_has_none(sinusoid):
    m = sinusoid.metrics
    assert set(m) == {"none", "static", "gms", "static_stiction"}
    assert m["none"].height == 0.0
    assert m["static"].height > 0.1e-6 and m["gms"].height > 0.5e-6 and m["static_stiction"].height > 1e-6
    for k in ("static", "gms", "static_stiction"):  # raw tracking error: friction adds to the linear error
        assert m[k].raw_peak_error > m["none"].raw_peak_error
    assert sinusoid.params["static_v_linear_m_s"] == PAPER_STATIC_V_LINEAR == 1e-4


def test_paper_claim_gms_glitch_above_static_above_none(sinusoid):
    """The paper: GMS gives larger glitches than the static map, which gives larger than none.
    Holds for the peak under the Simulink reading of the static map (linear region, no stiction)."""
    m = sinusoid.metrics
    assert m["gms"].height > 2.0 * m["static"].height > 0.0 == m["none"].height


def test_linear_region_static_glitch_is_the_ramp_disturbance_plateau(sinusoid):
    """Below v_linear the map is a viscous slope F(v_lin)/v_lin; through the reversal the reference
    velocity ramps at A w^2, so the friction is a ramp the PI loop follows with a constant error
    slope / (force_gain ki), for the 2 v_lin / (A w^2) = 5 s the reference spends in the region."""
    st = presets.paper_static_friction()
    vl = PAPER_STATIC_V_LINEAR
    acc = 0.01 * (2 * np.pi * 0.01) ** 2
    plateau = float(st.force([vl])[0]) / vl * acc / (presets.paper_plant().force_gain * DEFAULT_GAINS["ki"])
    m = sinusoid.metrics["static"]
    assert m.height == pytest.approx(plateau, rel=0.15)
    assert m.duration == pytest.approx(2 * vl / acc, rel=0.1)


def test_stiction_finding_static_map_spike_taller_but_shorter_than_gms(sinusoid):
    """The physical finding (docs/glitch.md): with true stiction the static map reverses the full
    friction abruptly and gives a taller, shorter spike than GMS, whose pre-sliding spreads the
    reversal over µm of travel.  The glitch area is set by the friction jump and ki for all."""
    m = sinusoid.metrics
    assert m["static_stiction"].height > 1.5 * m["gms"].height
    assert m["gms"].duration > 1.5 * m["static_stiction"].duration
    ki = scenario_controller().ki
    jump = 2 * presets.paper_static_friction().stribeck.fc
    for k in ("static", "gms", "static_stiction"):
        assert m[k].area == pytest.approx(jump / ki, rel=0.4)


@pytest.mark.parametrize("scale", [(0.5, 0.5, 0.5), (2, 2, 2), (0.5, 1, 1), (2, 1, 1), (1, 0.5, 1), (1, 2, 1)],
                         ids=["all x0.5", "all x2", "kp x0.5", "kp x2", "ki x0.5", "ki x2"])
def test_paper_ordering_is_robust_near_the_default(scale):
    """GMS > static > none for controller gains x0.5 / x2 and v_linear 5e-5 .. 2e-4 m/s."""
    ctrl = scenario_controller(*(DEFAULT_GAINS[k] * f for k, f in zip(("kp", "ki", "kd"), scale)), DEFAULT_GAINS["tf"])
    for vl in (5e-5, 2e-4):
        m = run_sinusoid(controller=ctrl, static_v_linear=vl, stiction=False, **FAST).metrics
        assert m["gms"].height > m["static"].height > m["none"].height == 0.0, (scale, vl)


def test_ordering_flips_near_true_stiction():
    """Where it stops holding: below v_linear ~ 2e-5 m/s the map acts like stiction (docs/glitch.md)."""
    m = run_sinusoid(static_v_linear=1e-5, stiction=False, **FAST).metrics
    assert m["static"].height > m["gms"].height
    m0 = run_sinusoid(static_v_linear=0.0, stiction=False, **FAST).metrics
    assert m0["static"].height == pytest.approx(3.9e-6, rel=0.05)


def test_gms_feedforward_cuts_glitch_80_percent_and_beats_static(compensation):
    """True machine: GMS.  Static-map feedforward from the paper's map under the same (Simulink)
    reading; the true-stiction map's feedforward is reported too and is worse than none."""
    c = compensation
    assert c.metrics["none"].height > 1e-6
    assert c.reduction("gms_feedforward") >= 80.0
    assert c.metrics["gms_feedforward"].height < c.metrics["static_feedforward"].height
    assert c.metrics["gms_feedforward"].height < c.metrics["static_feedforward_stiction"].height
    assert 0.0 < c.reduction("static_feedforward") < 50.0
    assert c.reduction("static_feedforward_stiction") < 0.0
    s = c.summary()
    assert set(s) == {"none", "static_feedforward", "gms_feedforward", "static_feedforward_stiction", "dob"}
    assert s["gms_feedforward"]["reduction_percent"] == pytest.approx(c.reduction("gms_feedforward"))


def test_disturbance_observer_cuts_glitch_without_a_friction_model(compensation):
    c = compensation
    assert c.reduction("dob") > 50.0
    assert c.feedforward["dob"] is None
    # a lower Q-filter cutoff observes less of the friction
    slow = run_compensation(extras=("dob",), dob_cutoff_hz=2.0, **FAST)
    assert c.reduction("dob") > slow.reduction("dob") > 0.0


def test_dob_is_transparent_without_disturbance():
    dt = 5e-4
    t, r, v0 = sinusoid_reference(0.01, 0.01, dt, 0.5)
    plant, pid = presets.paper_plant(), scenario_controller()
    base = simulate_closed_loop(plant, None, pid, r, dt, initial_velocity=v0)
    dob = simulate_closed_loop(plant, None, PIDDOB(pid, plant, 20.0), r, dt, initial_velocity=v0)
    after_start = t > 5.0  # the observer starts at rest while the axis moves: a start transient
    np.testing.assert_allclose(dob.position[after_start], base.position[after_start], atol=1e-9)
    with pytest.raises(InvalidInputError, match="dob_cutoff_hz"):
        PIDDOB(pid, plant, 0.0)
    with pytest.raises(InvalidInputError, match="dob_cutoff_hz"):  # above Nyquist: checked by the core
        simulate_closed_loop(plant, None, PIDDOB(pid, plant, 2e3), r, dt)
    with pytest.raises(InvalidInputError, match="extras"):
        run_compensation(extras=("lugre",), **FAST)


def test_feedforward_is_model_force_over_force_gain():
    t = np.arange(0, 2.0, 1e-3)
    r = 1e-3 * np.sin(2 * np.pi * 0.5 * t)
    st = presets.paper_static_friction()
    ff = friction_feedforward(st, t, r, 2.0)
    np.testing.assert_allclose(ff, st.force(np.gradient(r, t)) / 2.0)
    adv = friction_feedforward(st, t, r, 2.0, advance=0.01, gain=0.5)
    np.testing.assert_allclose(adv[:-20], 0.5 * ff[10:-10], atol=1e-3)
    with pytest.raises(InvalidInputError, match="force_gain"):
        friction_feedforward(st, t, r, 0.0)


def test_sweep_one_call_over_gains():
    rows = compensation_sweep({"kp": [2e4, 5e4], "ff_gain": [0.5, 1.0]}, dt=1e-3, periods=0.5)
    assert len(rows) == 2 * 2 * 3
    assert {r["strategy"] for r in rows} == {"none", "static_feedforward", "gms_feedforward"}
    full = [r for r in rows if r["ff_gain"] == 1.0 and r["strategy"] == "gms_feedforward"]
    half = [r for r in rows if r["ff_gain"] == 0.5 and r["strategy"] == "gms_feedforward"]
    for f, h in zip(full, half):
        assert f["reduction_percent"] > h["reduction_percent"]
    with pytest.raises(InvalidInputError, match="grid"):
        compensation_sweep({"gain": [1.0]})


def test_sweep_equals_individual_runs():
    """The sweep's rows are the individual run_compensation runs at the same gains."""
    strategies = ("none", "static_feedforward", "gms_feedforward", "static_feedforward_stiction", "dob")
    rows = compensation_sweep({"kp": [2.5e4, 5e4], "dob_cutoff_hz": [20.0]}, strategies=strategies, dt=1e-3, periods=0.5)
    assert len(rows) == 2 * len(strategies)
    for kp in (2.5e4, 5e4):
        ctrl = scenario_controller(kp=kp)
        single = run_compensation(controller=ctrl, dt=1e-3, periods=0.5).summary()
        for r in (r for r in rows if r["kp"] == kp):
            s = single[str(r["strategy"])]
            assert r["peak_error_m"] == pytest.approx(s["peak_error_m"], rel=1e-12, abs=1e-15)
            assert r["reduction_percent"] == pytest.approx(s["reduction_percent"], rel=1e-9, abs=1e-9)


def test_circle_quadrant_glitches():
    c = run_circle(dt=1e-3, frequency=0.02, lead_in=20.0)
    q = c.quadrant_glitch
    assert set(q["gms"]) == {0, 90, 180, 270}
    assert all(v == 0.0 for v in q["none"].values())
    for ang in (0, 90, 180, 270):  # outward spikes at every crossing, ordered as on the sinusoid
        assert q["static_stiction"][ang] > q["gms"][ang] > q["static"][ang] > 0.05e-6
    s = c.summary()
    assert s["static"]["peak_glitch_m"] == pytest.approx(max(q["static"].values()))
    with pytest.raises(InvalidInputError, match="radius"):
        run_circle(radius=-1.0)


def test_figures_are_returned(sinusoid, compensation):
    c = run_circle(dt=2e-3, frequency=0.05, lead_in=10.0)
    for fig in (plot_tracking_errors(sinusoid), plot_circle_polar(c), plot_compensation(compensation)):
        assert isinstance(fig, Figure) and fig.axes


def test_bad_scenario_input_names_argument():
    with pytest.raises(InvalidInputError, match="amplitude"):
        run_sinusoid(amplitude=0.0)
    with pytest.raises(InvalidInputError, match="plants"):
        run_sinusoid(plants={"lugre": presets.paper_plant()}, **FAST)


def test_cli_json_contract(tmp_path, capsys):
    out = tmp_path / "g.json"
    rc = gmsfric_main(["glitch", "--json", str(out), "--dt", "1e-3", "--frequency", "0.05", "--plot", str(tmp_path / "figs")])
    assert rc == 0
    d = json.loads(out.read_text())
    for k in ("none", "static", "gms", "static_stiction"):
        assert isinstance(d["sinusoid"][k]["peak_error_m"], float)
    for k in ("none", "static_feedforward", "gms_feedforward", "dob"):
        assert isinstance(d["compensation"][k]["peak_error_m"], float)
    assert d["parameters"]["static_v_linear_m_s"] == 1e-4
    assert set(d["circle"]["gms"]["quadrant_glitch_m"]) == {"0", "90", "180", "270"}
    assert len(list((tmp_path / "figs").glob("*.png"))) == 3


def test_cli_friction_file_and_bad_file(tmp_path):
    f = tmp_path / "static.json"
    f.write_text(json.dumps({"model": "static_map", "parameters": {n: {"value": v, "stderr": 0.0} for n, v in
                                                                   dict(fc=0.3, fs=0.35, vs=4.5e-4, sigma=7.0, delta=1.0).items()},
                             "units": {"fc": "N", "fs": "N", "vs": "m/s", "sigma": "N s/m", "delta": "1"}}))
    out = tmp_path / "g.json"
    assert gmsfric_main(["glitch", "--friction", str(f), "--json", str(out), "--dt", "1e-3", "--frequency", "0.05"]) == 0
    # --static-linear-region 0: the "static" entry is the true-stiction map
    assert gmsfric_main(["glitch", "--static-linear-region", "0", "--json", str(out), "--dt", "1e-3", "--frequency", "0.05"]) == 0
    d = json.loads(out.read_text())["sinusoid"]
    assert d["static"]["peak_error_m"] == d["static_stiction"]["peak_error_m"]
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert gmsfric_main(["glitch", "--friction", str(bad), "--dt", "1e-3"]) == 2


def test_friction_and_plant_files_in_any_unit_are_read_in_si(tmp_path):
    """The factor-1000 bugs: sigma in N/(mm/s), stiffness in mN/um, a plant's force gain."""
    from gmsfric.glitch.cli import _frictions_from, _plant_from
    from gmsfric.model_io import save_model

    sf = tmp_path / "static.json"
    sf.write_text(json.dumps({"model": "static_map", "parameters": {n: {"value": v} for n, v in dict(fc=0.18, fs=0.21, vs=0.45, sigma=6.98e-3, delta=1.0).items()},
                              "units": {"fc": "N", "fs": "N", "vs": "mm/s", "sigma": "N/(mm/s)", "delta": "1"}}))
    bf = tmp_path / "blocks.json"
    bf.write_text(json.dumps({"model": "presliding", "parameters": {"k1": {"value": 3200.0}, "k2": {"value": 8.9}, "w1": {"value": 33.0}, "w2": {"value": 57.0}},
                              "units": {"k1": "mN/um", "k2": "mN/um", "w1": "mN", "w2": "mN"}}))
    static, gms = _frictions_from([str(sf), str(bf)])
    assert static.sigma == pytest.approx(6.98) and static.stribeck.vs == pytest.approx(4.5e-4)
    assert gms.k == pytest.approx((3.2e6, 8.9e3)) and gms.alpha == pytest.approx((33 / 90, 57 / 90))
    assert gms.stribeck == static.stribeck and gms.c == pytest.approx(1 / 4.5e-4)
    pf = tmp_path / "plant.json"
    save_model(presets.emps_plant(), pf)
    assert _plant_from(str(pf)) == presets.emps_plant()  # 35.15 N/V, not 1
    pf.write_text(json.dumps({"model": "plant", "parameters": {"a": 19.85, "b": 168.4, "c": 176.8, "delay": 1.29},
                              "units": {"a": "mm/(V s^2)", "b": "1/s", "c": "1/s^2", "delay": "ms"}}))
    with pytest.raises(InvalidInputError, match="no force gain"):
        _plant_from(str(pf))
