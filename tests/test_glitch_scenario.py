"""The paper's Section 4.2 scenario, the circle test and friction feedforward (physics runs).

Coarse step (5e-4 s; the core's GMS update is exact at any step) and half a period (one
reversal) keep these fast; the metrics agree with the 1e-4 s full-period run to < 0.1 %.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.figure import Figure

from gmsfric import presets
from gmsfric.errors import InvalidInputError
from gmsfric.glitch import (
    compensation_sweep,
    friction_feedforward,
    plot_circle_polar,
    plot_compensation,
    plot_tracking_errors,
    run_circle,
    run_compensation,
    run_sinusoid,
    scenario_controller,
)
from gmsfric.glitch import cli as glitch_cli

FAST = dict(dt=5e-4, periods=0.5)


@pytest.fixture(scope="module")
def sinusoid():
    return run_sinusoid(**FAST)


@pytest.fixture(scope="module")
def compensation():
    return run_compensation(**FAST)


def test_friction_makes_glitches_and_none_has_none(sinusoid):
    m = sinusoid.metrics
    assert m["none"].height == 0.0
    assert m["static"].height > 1e-6 and m["gms"].height > 0.5e-6
    # raw tracking error at the glitch: friction adds to the linear error
    assert m["none"].raw_peak_error < m["gms"].raw_peak_error < m["static"].raw_peak_error


def test_paper_claim_gms_glitch_lasts_longer_than_static(sinusoid):
    """The paper: GMS gives larger glitches than the static map, which gives larger than none.
    Holds for the glitch duration (pre-sliding spreads the friction reversal over µm of travel)."""
    m = sinusoid.metrics
    assert m["gms"].duration > 1.5 * m["static"].duration > m["none"].duration == 0.0


def test_peak_height_ordering_is_static_above_gms(sinusoid):
    """The contrary finding (docs/glitch.md): the abrupt static-map reversal gives the taller
    spike; the glitch area is set by the friction jump and the integral gain for both models."""
    m = sinusoid.metrics
    assert m["static"].height > 1.5 * m["gms"].height
    ki = scenario_controller().ki
    jump = 2 * presets.paper_static_friction().stribeck.fc
    for k in ("static", "gms"):
        assert m[k].area == pytest.approx(jump / ki, rel=0.35)


def test_gms_feedforward_cuts_glitch_80_percent_and_beats_static(compensation):
    c = compensation
    assert c.metrics["none"].height > 1e-6
    assert c.reduction("gms_feedforward") >= 80.0
    assert c.metrics["gms_feedforward"].height < c.metrics["static_feedforward"].height
    s = c.summary()
    assert set(s) == {"none", "static_feedforward", "gms_feedforward"}
    assert s["gms_feedforward"]["reduction_percent"] == pytest.approx(c.reduction("gms_feedforward"))


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
    full = [r for r in rows if r["ff_gain"] == 1.0 and r["strategy"] == "gms_feedforward"]
    half = [r for r in rows if r["ff_gain"] == 0.5 and r["strategy"] == "gms_feedforward"]
    for f, h in zip(full, half):
        assert f["reduction_percent"] > h["reduction_percent"]
    with pytest.raises(InvalidInputError, match="grid"):
        compensation_sweep({"gain": [1.0]})


def test_circle_quadrant_glitches():
    c = run_circle(dt=1e-3, frequency=0.02, lead_in=20.0)
    q = c.quadrant_glitch
    assert set(q["gms"]) == {0, 90, 180, 270}
    assert all(v == 0.0 for v in q["none"].values())
    for ang in (0, 90, 180, 270):
        assert q["static"][ang] > q["gms"][ang] > 0.2e-6  # outward spikes at every crossing
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
    rc = glitch_cli.main(["--json", str(out), "--dt", "1e-3", "--frequency", "0.05", "--plot", str(tmp_path / "figs")])
    assert rc == 0
    d = json.loads(out.read_text())
    for k in ("none", "static", "gms"):
        assert isinstance(d["sinusoid"][k]["peak_error_m"], float)
    for k in ("none", "static_feedforward", "gms_feedforward"):
        assert isinstance(d["compensation"][k]["peak_error_m"], float)
    assert set(d["circle"]["gms"]["quadrant_glitch_m"]) == {"0", "90", "180", "270"}
    assert len(list((tmp_path / "figs").glob("*.png"))) == 3


def test_cli_friction_file_and_bad_file(tmp_path):
    f = tmp_path / "static.json"
    f.write_text(json.dumps({"model": "static_map", "parameters": {n: {"value": v, "stderr": 0.0} for n, v in
                                                                   dict(fc=0.3, fs=0.35, vs=4.5e-4, sigma=7.0, delta=1.0).items()}}))
    out = tmp_path / "g.json"
    assert glitch_cli.main(["--friction", str(f), "--json", str(out), "--dt", "1e-3", "--frequency", "0.05"]) == 0
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    assert glitch_cli.main(["--friction", str(bad), "--dt", "1e-3"]) == 2
