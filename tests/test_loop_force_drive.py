"""`gmsfric loop --force`: the drive is the force itself.  The embedded axis model states no
invented drive gain (command unit N, force gain 1 N/N), the closed-loop gains are in force
units, and a replay far off the measured loop is reported."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import gmsfric as g
from gmsfric import units
from gmsfric.cli import main
from gmsfric.errors import FitWarning
from gmsfric.loop import LoopConfig, closed_loop_report, run_loop
from gmsfric.loop.axis_model import to_axis_model
from gmsfric.loop.checks import CLOSED_LOOP_FLOOR_PCT, check_closed_loop
from gmsfric.loop.rigs import Rig, rig_pair
from gmsfric.model_io import ModelFormatError
from gmsfric.system import Cascade

RIG = Rig(effect=None, seed=23, fs=500.0, duration=12.0)
#: The rig's cascade with its velocity gain turned from V per m/s into N per m/s.
KV_FORCE = RIG.controller().kv * RIG.gain


def _write(path, d, *, with_disturbance=False):
    cols = [d.t, d.position, d.force, d.reference]
    names = "t,x,F,ref"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=names, comments="", fmt="%.17g")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    est, val = rig_pair(RIG)
    tmp = tmp_path_factory.mktemp("force")
    return est, val, _write(tmp / "est.csv", est), _write(tmp / "val.csv", val)


@pytest.fixture(scope="module")
def cli_json(runs, tmp_path_factory):
    _, _, est_csv, val_csv = runs
    out = tmp_path_factory.mktemp("out") / "loop.json"
    assert main(["loop", str(est_csv), "--validate", str(val_csv), "--time", "t", "--position", "x", "--force", "F",
                 "--reference", "ref", "--kp", str(RIG.controller().kp), "--kv", str(KV_FORCE), "--json", str(out), "--quiet"]) == 0
    return out


def test_force_column_model_states_no_volt_gain(cli_json):
    d = json.loads(cli_json.read_text())
    m = d["gmsfric_model"]
    assert m["options"]["command_unit"] == "N"
    assert m["parameters"]["plant.force_gain"] == {"value": 1.0, "unit": "N/N"}
    assert m["parameters"]["plant.a"]["unit"] == "m/(N s^2)"
    assert "V" not in json.dumps(m["parameters"]) and "V" not in json.dumps(m.get("covariance", {}).get("units", []))


def test_force_column_model_round_trips(cli_json, tmp_path):
    axis = g.load_model(cli_json)
    assert axis.units.command == "N" and axis.plant.force_gain == 1.0 and axis.plant.drive == "N"
    assert axis.plant.mass == pytest.approx(RIG.mass, rel=0.05)
    g.save_model(axis, tmp_path / "m.json")
    again = g.load_model(tmp_path / "m.json")
    assert again == axis
    assert json.loads((tmp_path / "m.json").read_text())["parameters"]["plant.force_gain"]["unit"] == "N/N"


def test_force_column_gains_in_force_units_replay_the_loop(cli_json):
    """--kv in N s/m (the rig's V s/m times its N/V) replays the measured loop closely, with no
    closed-loop diagnostic."""
    d = json.loads(cli_json.read_text())
    for model in ("baseline", "final"):
        for run in ("estimation", "validation"):
            e = d["closed_loop"][model][run]
            assert e["force_pct"] < 10 and e["acceleration_pct"] < 15, (model, run, e)
    assert not [x for x in d["diagnostics"] if x["parameter"] == "closed_loop"]


def test_replay_far_off_the_loop_is_reported(runs):
    """The same gains read as V s/m on a force drive (35x too weak on EMPS, 30x on this rig):
    the replay misses the force by far more than the inverse model, and says so."""
    est, val, _, _ = runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        from gmsfric.loop.data import AxisData

        strip = lambda d: AxisData(t=d.t, position=d.position, force=d.force, source=d.source, reference=d.reference)  # noqa: E731
        result = run_loop(strip(est), strip(val), LoopConfig(progress=False))
    weak = Cascade(RIG.controller().kp, RIG.controller().kv)
    result.closed_loop, result.closed_loop_runs = closed_loop_report({"baseline": result.baseline, "final": result.final},
                                                                     {"estimation": result.split.est, "validation": result.split.val}, weak)
    assert max(r["force_pct"] for m in result.closed_loop.values() for r in m.values()) > CLOSED_LOOP_FLOOR_PCT
    found = check_closed_loop(result, weak)
    assert found.has("poor_fit", "closed_loop")
    msg = next(x.message for x in found.items if x.parameter == "closed_loop")
    assert "N s/m" in msg and "--kv" in msg
    # a drive held at its limit is reported too
    tight = Cascade(RIG.controller().kp, KV_FORCE, -5.0, 5.0)
    result.closed_loop, result.closed_loop_runs = closed_loop_report({"final": result.final}, {"estimation": result.split.est}, tight)
    assert check_closed_loop(result, tight).has("saturation", "closed_loop")
    # and the right gains report nothing
    good = Cascade(RIG.controller().kp, KV_FORCE)
    result.closed_loop, result.closed_loop_runs = closed_loop_report({"final": result.final}, {"estimation": result.split.est}, good)
    assert len(check_closed_loop(result, good)) == 0


def test_rotary_force_drive_units(runs, tmp_path):
    est, val, _, _ = runs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FitWarning)
        result = run_loop(est, val, LoopConfig(progress=False))
    sig = result.split.est
    axis = to_axis_model(result.baseline, sig, gain=None, kind="rotary")
    assert axis.units.command == "N m" and axis.plant.drive == "N m"
    doc = axis.model_document()
    assert doc["parameters"]["plant.force_gain"]["unit"] == "N m/(N m)" and doc["parameters"]["plant.a"]["unit"] == "rad/(N m s^2)"
    g.save_model(axis, tmp_path / "rot.json")
    assert g.load_model(tmp_path / "rot.json") == axis
    # a command run keeps its volts and its drive gain
    volt = to_axis_model(result.baseline, sig, gain=RIG.gain)
    assert volt.units.command == "V" and volt.model_document()["parameters"]["plant.force_gain"] == {"value": RIG.gain, "unit": "N/V"}


def test_force_drive_units_table():
    assert units.si_unit("force_gain", drive="N") == "N/N" and units.si_unit("plant_gain", drive="N") == "m/(N s^2)"
    assert units.si_unit("force_gain", True, drive="N m") == "N m/(N m)"
    assert units.drive_base("mN") == "N" and units.drive_base("N m") == "N m" and units.drive_base("mV") == "V"
    assert units.drive_of("mN/N", "force_gain", rotary=False) == "N" and units.drive_of("N/A", "force_gain", rotary=False) == "A"
    assert units.to_si(1.0, "mm/(N s^2)", "plant_gain", rotary=False) == pytest.approx(1e-3)
    with pytest.raises(units.UnitError, match="drive"):
        units.si_unit("force_gain", True, drive="N")  # a linear force drive on a rotary axis


def test_mixed_drives_are_refused(cli_json, tmp_path):
    """A plant per newton with a command in volts (or a force gain per volt) would scale the
    friction: refused, never relabeled."""
    doc = json.loads(cli_json.read_text())["gmsfric_model"]
    bad = json.loads(json.dumps(doc))
    bad["options"]["command_unit"] = "V"
    (tmp_path / "a.json").write_text(json.dumps(bad))
    with pytest.raises(ModelFormatError, match="command is in V"):
        g.load_model(tmp_path / "a.json")
    bad = json.loads(json.dumps(doc))
    bad["parameters"]["plant.force_gain"]["unit"] = "N/V"
    (tmp_path / "b.json").write_text(json.dumps(bad))
    with pytest.raises(ModelFormatError, match="same drive"):
        g.load_model(tmp_path / "b.json")


def test_help_states_the_gain_units(capsys):
    try:
        assert main(["loop", "--help"]) == 0
    except SystemExit as exc:  # argparse's own exit
        assert exc.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "command units per m/s with --command" in text and "N s/m" in text and "1/s" in text
