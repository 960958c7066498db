"""Models move between commands through model files without losing anything."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import gmsfric as g
from gmsfric.loop import LoopConfig, load_axis_data, run_loop

EMPS = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "emps"


def full_axis() -> g.AxisModel:
    return g.AxisModel(
        g.Plant.from_mass(2.0, force_gain=35.0, delay=3e-4),
        g.StaticFriction(g.Stribeck(20.0, 9.0, 0.013), 200.0, offset=-3.0),
        g.Effects(
            asymmetry=(0.3, -37.0),
            position_force=g.PositionSeries.fourier([2.5e-3], 2, [0.1, 0.2, 0.3, 0.4]),
            position_friction=g.PositionSeries.legendre(-0.1, 0.1, [0.0, 1.0, -0.5], beyond="linear"),
            heating=g.Heating(30.0, -5.0, 0.0),
            drift=g.Drift("exponential", 25.0, 1.0, 2.0),
            blocks=g.MaxwellSlip([1e6, 2e5], [1.0, 2.0]),
            compliance=g.Compliance(0.5, 40.0, 0.1),
        ),
        g.AxisUnits("rotary", "A"),
        g.Covariance(("friction.sigma", "friction.stribeck.fc", "effects.asymmetry.1"), np.diag([4.0, 0.01, 1.0])),
        {"command": "test"},
    )


def test_an_axis_model_with_every_effect_round_trips(tmp_path: Path) -> None:
    m = full_axis()
    path = g.save_model(m, tmp_path / "axis.json")
    back = g.load_model(path)
    assert back == m
    u = np.full(3000, 0.5)
    np.testing.assert_array_equal(back.simulate(1e-3, command=u).position, m.simulate(1e-3, command=u).position)


def test_a_unit_changed_in_the_file_is_converted_and_an_unknown_one_refused(tmp_path: Path) -> None:
    import json

    m = full_axis()
    doc = m.model_document()
    # Same friction level written in mN m: read back in SI.
    doc["parameters"]["friction.fc"] = {"value": 20.0e3, "unit": "mN m"}
    (tmp_path / "a.json").write_text(json.dumps(doc))
    assert g.load_model(tmp_path / "a.json").friction.stribeck.fc == pytest.approx(20.0)
    doc["parameters"]["friction.fc"] = {"value": 20.0, "unit": "furlong"}
    (tmp_path / "b.json").write_text(json.dumps(doc))
    with pytest.raises(g.InvalidInputError, match="furlong"):
        g.load_model(tmp_path / "b.json")
    doc["parameters"]["friction.fc"] = {"value": 20.0, "unit": "N"}  # a linear unit on a rotary axis
    (tmp_path / "c.json").write_text(json.dumps(doc))
    with pytest.raises(g.InvalidInputError):
        g.load_model(tmp_path / "c.json")


@pytest.mark.skipif(not EMPS.exists(), reason="EMPS data not beside the repository")
def test_the_loops_emps_result_loads_and_simulates_with_its_effects_in_feedback(tmp_path: Path) -> None:
    kw = dict(time="t", position="qm", command="vir", gain="gtau", reference="qg")
    est = load_axis_data(EMPS / "DATA_EMPS.mat", **kw)
    val = load_axis_data(EMPS / "DATA_EMPS_PULSES.mat", disturbance="pulses_N", **kw)
    res = run_loop(est, val, LoopConfig(progress=False))
    json_path = tmp_path / "loop.json"
    res.to_json(json_path)
    model = g.load_model(json_path)
    assert isinstance(model, g.AxisModel)
    assert model.effects.names, "the accepted effects are in the model"
    direct = res.axis_model()
    assert model.parameters() == pytest.approx(direct.parameters(), rel=1e-12)
    from gmsfric import presets
    from gmsfric.loop.closedloop import initial_state

    q0, v0 = initial_state(val.t, val.position)
    sim = model.simulate(1e-3, reference=val.reference, controller=presets.emps_controller(), input_disturbance=val.disturbance,
                         initial_position=q0, initial_velocity=v0)
    err = 100 * np.linalg.norm(val.force - val.gain * sim.command) / np.linalg.norm(val.force)
    assert err < 5.0, f"closed-loop force error on the pulses run {err:.2f} %"


def test_save_model_of_an_axis_model_never_relabels_it_and_keeps_covariance_and_provenance(tmp_path: Path) -> None:
    import dataclasses
    import json

    rot = full_axis()
    lin = dataclasses.replace(rot, units=g.AxisUnits("linear", "A"))
    with pytest.raises(g.InvalidInputError, match="`rotary`=True would relabel `model`, a linear-axis model"):
        g.save_model(lin, tmp_path / "lin.json", rotary=True)
    with pytest.raises(g.InvalidInputError, match="`rotary`=False would relabel"):
        g.save_model(rot, tmp_path / "rot.json", rotary=False)
    assert not list(tmp_path.iterdir())
    # confirming its own axis, or adding provenance, keeps the covariance and provenance
    path = g.save_model(rot, tmp_path / "rot.json", rotary=True, provenance={"note": "kept"})
    doc = json.loads(path.read_text())
    assert doc["axis"] == "rotary" and doc["covariance"]["names"] == list(rot.covariance.names)
    assert doc["provenance"]["command"] == "test" and doc["provenance"]["note"] == "kept"
    back = g.load_model(path)
    assert back.covariance is not None and back.units == rot.units and back.plant == rot.plant


def test_a_series_beyond_its_travel_keeps_its_rule_and_older_files_hold_it(tmp_path: Path) -> None:
    import json

    doc = full_axis().model_document()
    assert doc["options"]["effects.position_friction.beyond"] == "linear"
    del doc["options"]["effects.position_friction.beyond"]  # as written before the option existed
    (tmp_path / "old.json").write_text(json.dumps(doc))
    old = g.load_model(tmp_path / "old.json").effects.position_friction
    assert old is not None and old.beyond == "hold"
    assert old(np.array([0.5]))[0] == pytest.approx(old(np.array([0.1]))[0])
    doc["options"]["effects.position_friction.beyond"] = "quadratic"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(g.DataError, match="effects.position_friction.beyond"):
        g.load_model(tmp_path / "bad.json")
