"""`gmsfric loop --fit simulation --open-loop`: the loop's models refined by closed-loop
simulation error and scored by open-loop simulation (the EMPS benchmark's protocol)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

import gmsfric as g
from gmsfric.cli import main
from gmsfric.loop import LoopConfig, closed_loop_report, run_loop
from gmsfric.loop.closedloop import initial_state
from gmsfric.loop.rigs import Rig, rig_pair, simulate_rig
from gmsfric.loop.simulation import OPEN_LOOP_SKIP, SimulationLoopResult, add_simulation, open_loop_rmse

from conftest import EMPS_DIR

RIG = Rig(effect="asymmetric_friction", seed=7, fs=500.0, duration=12.0)


@pytest.fixture(scope="module")
def refined():
    est, val = rig_pair(RIG)
    result = run_loop(est, val, LoopConfig(progress=False))
    before, _ = closed_loop_report({"final": result.final}, {"estimation": result.split.est}, RIG.controller())
    return result, add_simulation(result, RIG.controller(), fit=True, open_loop=True, progress=False), before


def test_json_fields_and_what_closed_loop_describes(refined):
    _, res, _ = refined
    assert isinstance(res, SimulationLoopResult)
    d = res.to_dict()
    assert set(d["open_loop"]) == {"baseline", "final"}
    for scores in d["open_loop"].values():
        assert set(scores) == {"estimation_rmse_m", "validation_rmse_m"}
        assert all(0 < v < 0.05 for v in scores.values())  # metres: a few mm of drift at most on this rig
    sf = d["simulation_fit"]
    assert sf["closed_loop_models"] == "refined" and set(sf) >= {"baseline", "final", "method"}
    assert set(d["closed_loop"]) == {"baseline", "final"} and set(d["closed_loop"]["final"]) == {"estimation", "validation"}
    assert sf["final"]["parameters"]["plant.a"]["unit"] == "m/(V s^2)"
    # the loop's own fields are untouched
    assert {"baseline", "final", "steps", "alignment", "unexplained"} <= set(d)
    text = res.table()
    assert "refined by closed-loop simulation error" in text and "open-loop simulation RMSE" in text


def test_refinement_does_not_simulate_worse(refined):
    """The refined final model reproduces the estimation run's command at least as well in
    closed loop as the inverse-model fit it started from (it minimised exactly that, with the
    position)."""
    _, res, before = refined
    fit = res.refined["final"]
    c = fit.channels["command"]
    assert c["relative_error_pct"] <= c["relative_error_start_pct"] * 1.001
    assert c["relative_error_start_pct"] == pytest.approx(before["final"]["estimation"]["force_pct"], rel=1e-3)
    assert res.closed_loop["final"]["estimation"]["force_pct"] <= before["final"]["estimation"]["force_pct"] * 1.001


def test_embedded_model_is_the_refined_final(refined, tmp_path):
    _, res, _ = refined
    p = tmp_path / "loop.json"
    res.to_json(p)
    back = g.load_model(p)
    want = res.refined["final"].model
    assert back.parameters() == pytest.approx(want.parameters())
    assert back.covariance is not None and back.covariance.names == want.covariance.names


def test_open_loop_protocol(refined):
    """The score is the RMS position error of the open-loop simulation from the measured command,
    started from the measured state, after the first 20 samples."""
    result, res, _ = refined
    data = result.split.val.data
    axis = res.axis_model()
    q0, v0 = initial_state(data.t, data.position)
    sim = axis.simulate(data.dt, command=data.command, initial_position=q0, initial_velocity=v0).position
    want = np.sqrt(np.mean((sim - data.position)[OPEN_LOOP_SKIP:] ** 2))
    assert res.open_loop["final"]["validation_rmse_m"] == pytest.approx(want, rel=1e-12)
    assert open_loop_rmse(axis, data) == pytest.approx(want, rel=1e-12)


def test_open_loop_of_the_truth_is_the_encoder():
    """On a clean rig the true axis, run open loop from the recorded command, stays within a few
    encoder counts of the record (force noise and quantisation only)."""
    rig = replace(RIG, effect=None, force_noise=0.0)
    data = simulate_rig(rig)
    truth = g.AxisModel(g.Plant.from_mass(rig.mass, force_gain=rig.gain), g.StaticFriction(g.Stribeck(rig.fc, rig.fc, 1.0), sigma=rig.fv, offset=rig.offset))
    assert open_loop_rmse(truth, data) < 5 * rig.quantization
    wrong = truth.with_parameters({"friction.sigma": 1.05 * rig.fv})
    assert open_loop_rmse(wrong, data) > 100 * rig.quantization


def test_without_validation_run_the_validation_score_is_null():
    est, _ = rig_pair(RIG)
    result = run_loop(est, None, LoopConfig(progress=False, effects=("asymmetric_friction",)))
    res = add_simulation(result, None, open_loop=True)
    assert res.open_loop["final"]["validation_rmse_m"] is None and res.open_loop["final"]["estimation_rmse_m"] > 0
    with pytest.raises(g.InvalidInputError, match="needs the controller"):
        add_simulation(result, None, fit=True)


@pytest.fixture(scope="module")
def rig_csv(tmp_path_factory):
    d = simulate_rig(replace(RIG, duration=6.0))
    path = tmp_path_factory.mktemp("rig") / "rig.csv"
    cols = np.column_stack([d.t, d.position, d.command, d.reference])
    np.savetxt(path, cols, delimiter=",", header="t,x,u,ref", comments="")
    return path


def test_cli_fit_simulation_and_open_loop(rig_csv, tmp_path):
    out = tmp_path / "r.json"
    argv = ["loop", str(rig_csv), "--time", "t", "--position", "x", "--command", "u", "--gain", str(RIG.gain), "--reference", "ref",
            "--kp", "160", "--kv", str(2.56 * RIG.mass), "--fit", "simulation", "--open-loop", "--json", str(out), "--quiet"]
    assert main(argv) == 0
    d = json.loads(out.read_text())
    assert d["simulation_fit"]["closed_loop_models"] == "refined"
    assert set(d["open_loop"]["final"]) == {"estimation_rmse_m", "validation_rmse_m"} and d["open_loop"]["final"]["validation_rmse_m"] is None
    assert set(d["closed_loop"]["final"]) == {"estimation"}


def test_cli_fit_simulation_needs_the_closed_loop(rig_csv, capsys):
    argv = ["loop", str(rig_csv), "--time", "t", "--position", "x", "--command", "u", "--gain", "30", "--fit", "simulation", "--quiet"]
    assert main(argv) == 2
    assert "--fit simulation needs the closed-loop simulation" in capsys.readouterr().err


EST, VAL = EMPS_DIR / "DATA_EMPS.mat", EMPS_DIR / "DATA_EMPS_PULSES.mat"


@pytest.mark.slow
@pytest.mark.skipif(not (EST.exists() and VAL.exists()), reason="EMPS data not found next to the repository")
def test_emps_fit_simulation_open_loop(tmp_path):
    """The whole EMPS command (about 20 s): refined models in closed loop, the benchmark's
    open-loop score in metres, and a refined final model that simulates the estimation run's
    force better than 4 %."""
    out = tmp_path / "emps.json"
    argv = ["loop", str(EST), "--validate", str(VAL), "--time", "t", "--position", "qm", "--command", "vir", "--gain", "gtau",
            "--reference", "qg", "--disturbance", "pulses_N", "--kp", "kp", "--kv", "kv", "--drive-limit", "10",
            "--fit", "simulation", "--open-loop", "--json", str(out), "--quiet"]
    assert main(argv) == 0
    d = json.loads(out.read_text())
    for name in ("baseline", "final"):
        ol = d["open_loop"][name]
        assert 1e-3 < ol["estimation_rmse_m"] < 0.05 and 1e-3 < ol["validation_rmse_m"] < 0.05
    cl = d["closed_loop"]["final"]
    assert cl["estimation"]["force_pct"] < 4.0 and cl["validation"]["force_pct"] < d["closed_loop"]["baseline"]["validation"]["force_pct"]
    fit = d["simulation_fit"]["final"]
    assert fit["channels"]["command"]["relative_error_pct"] <= fit["channels"]["command"]["relative_error_start_pct"] * 1.001
    assert fit["parameters"]["plant.a"]["std"] > 0
