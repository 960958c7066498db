"""The `gmsfric identify ...` and `gmsfric paper` contract: names, JSON fields, errors."""

import json

import numpy as np
import pytest
from scipy.io import savemat

from gmsfric import PID, GMS, Plant, presets
from gmsfric.cli import main
from gmsfric.identify import VirtualRig, static_map_curve
from gmsfric.identify.paper import ReplaySettings, replay_paper


def _csv(path, cols):
    names = list(cols)
    data = np.column_stack([cols[n] for n in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="")
    return str(path)


def test_static_map_table_csv_json_and_plot(tmp_path, capsys):
    v = np.concatenate([np.geomspace(0.01, 30, 14), -np.geomspace(0.01, 30, 14)])  # mm/s
    F = static_map_curve(v, 0.2, 0.3, 0.5, 0.01, 1.0) + 1e-4 * np.random.default_rng(0).standard_normal(v.size)
    f = _csv(tmp_path / "map.csv", {"vel": v, "F": F})
    out = tmp_path / "map.json"
    assert main(["identify", "static-map", f, "--velocity", "vel", "--force", "F", "--json", str(out), "--plot", str(tmp_path / "figs"), "--velocity-unit", "mm/s"]) == 0
    text = capsys.readouterr().out
    assert "fc" in text and "stderr" in text
    js = json.loads(out.read_text())
    assert js["model"] == "static_map"
    assert list(js["parameters"]) == ["fc", "fs", "vs", "sigma", "delta"]
    assert js["parameters"]["vs"]["value"] == pytest.approx(0.5, rel=0.05)  # the data's own units
    assert all(isinstance(p["stderr"], float) for p in js["parameters"].values())
    assert list((tmp_path / "figs").glob("*.png"))


def test_static_map_raw_run_from_mat(tmp_path, capsys):
    rig = VirtualRig(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(presets.PaperReading(drive_limit=1e3)), encoder=5e-7, force_noise=1e-3)
    run = rig.constant_velocity_run(np.array([0.05, 0.1, 0.3, 1, 3, 8]) * 1e-3, min_travel=1e-4, max_travel=3e-3, seed=1)
    f = tmp_path / "run.mat"
    savemat(f, {"t": run["t"], "q": run["position"], "force": run["force"]})
    out = tmp_path / "run.json"
    assert main(["identify", "static-map", str(f), "--time", "t", "--position", "q", "--force", "force", "--json", str(out), "--quiet"]) == 0
    js = json.loads(out.read_text())
    assert js["n_plateaus"] >= 10
    assert js["parameters"]["fc"]["value"] == pytest.approx(0.1826, rel=0.02)


def test_presliding_cli(tmp_path):
    g = GMS.from_break_forces([1e6, 1e5], [1.0, 2.0], 1e5)
    d = VirtualRig(Plant(1.0, 0, 0), g, None, encoder=1e-9, force_noise=1e-3).sinusoid_test([2e-6, 1e-4], 0.5, cycles=2, seed=0)
    f = _csv(tmp_path / "sine.csv", {"time": d["t"], "x": d["position"], "F": d["force"]})
    out = tmp_path / "ps.json"
    assert main(["identify", "presliding", f, "--time", "time", "--position", "x", "--force", "F", "--blocks", "2", "--json", str(out), "--plot", str(tmp_path / "p"), "--quiet"]) == 0
    js = json.loads(out.read_text())
    assert js["model"] == "presliding"
    assert list(js["parameters"]) == ["k1", "k2", "w1", "w2"]
    assert js["parameters"]["w1"]["value"] == pytest.approx(1.0, rel=0.03)
    assert js["parameters"]["k2"]["value"] == pytest.approx(1e5, rel=0.03)
    names = {p.name for p in (tmp_path / "p").glob("*.png")}
    assert any("virgin" in n for n in names)


def test_plant_cli(tmp_path):
    plant = presets.paper_plant()
    d = VirtualRig(plant, None, None, dt=5e-4, encoder=5e-7).noise_test(10.0, 5.0, (0.5, 300.0), seed=3)
    f = _csv(tmp_path / "frf.csv", {"t": d["t"], "u": d["input"], "y": d["output"]})
    out = tmp_path / "plant.json"
    assert main(["identify", "plant", f, "--time", "t", "--input", "u", "--output", "y", "--fmin", "1", "--fmax", "300", "--json", str(out), "--plot", str(tmp_path / "b")]) == 0
    js = json.loads(out.read_text())
    assert js["model"] == "plant" and list(js["parameters"]) == ["a", "b", "c", "delay"]
    assert js["parameters"]["delay"]["value"] == pytest.approx(1.29e-3, rel=0.03)
    assert js["parameters"]["a"]["value"] == pytest.approx(plant.a, rel=0.01)
    # without --force-gain the plant cannot be loaded (a default 1 N/V would scale friction silently)
    from gmsfric import InvalidInputError, load_model

    with pytest.raises(InvalidInputError, match="--force-gain"):
        load_model(out)
    assert main(["identify", "plant", f, "--time", "t", "--input", "u", "--output", "y", "--fmin", "1", "--fmax", "300", "--force-gain", "35.15",
                 "--json", str(out), "-q"]) == 0
    js = json.loads(out.read_text())
    assert js["force_gain"] == 35.15 and js["units"]["force_gain"] == "N/V" and list(js["parameters"]) == ["a", "b", "c", "delay"]
    loaded = load_model(out)
    assert loaded.force_gain == 35.15 and loaded.a == pytest.approx(plant.a, rel=0.01)


@pytest.mark.parametrize(
    "content, args, message",
    [
        ("t,x,F\n0,0,0\n", ["--time", "t", "--position", "nope", "--force", "F"], "unknown position column 'nope'"),
        ("", ["--time", "t", "--position", "x", "--force", "F"], "empty"),
        ("t,x,F\n0,a,0\n1,2,3\n", ["--time", "t", "--position", "x", "--force", "F"], "data row 1, column 'x': 'a' is not a number"),
    ],
)
def test_bad_files_give_clear_errors(tmp_path, capsys, content, args, message):
    f = tmp_path / "bad.csv"
    f.write_text(content)
    assert main(["identify", "presliding", str(f), *args]) == 2
    assert message in capsys.readouterr().err


def test_too_few_plateaus_cli(tmp_path, capsys):
    t = np.arange(3000) * 1e-3
    x = np.minimum(t, 1.5) * 1e-3
    f = _csv(tmp_path / "one.csv", {"t": t, "x": x, "F": np.ones_like(t)})
    assert main(["identify", "static-map", f, "--time", "t", "--position", "x", "--force", "F", "--quiet"]) == 1  # a fit that failed
    assert "too few constant-velocity plateaus" in capsys.readouterr().err


def test_unknown_velocity_column(tmp_path, capsys):
    f = _csv(tmp_path / "m.csv", {"v": np.arange(1.0, 11.0), "F": np.ones(10)})
    assert main(["identify", "static-map", f, "--velocity", "speed", "--force", "F"]) == 2
    assert "unknown velocity column 'speed'" in capsys.readouterr().err


def test_paper_replay_quick():
    """The whole paper on the rig (short records): identified vs true within the uncertainty."""
    s = ReplaySettings(
        velocities=tuple(v * 1e-3 for v in (0.01, 0.03, 0.1, 0.3, 0.5, 1, 2, 4, 8, 14, 20, 30)),
        frf_duration=12.0, sine_cycles=2, dt=1e-3, seed=1,
    )
    rep = replay_paper(s, progress=False)
    assert len(rep.tables) == 5
    t1 = next(v for k, v in rep.tables.items() if k.startswith("Table 1"))
    t2 = next(v for k, v in rep.tables.items() if k.startswith("Table 2"))
    for row in t1 + t2:
        assert abs(row["value"] / row["true"] - 1) < 0.05, row
        assert abs(row["z"]) < 4, row
    gms_rev = next(v for k, v in rep.tables.items() if "GMS model in the loop" in k)
    for row in gms_rev:  # A', B' within 2 %; C' (acts below ~2 Hz) through its uncertainty
        assert abs(row["z"]) < 3, row
        if row["name"] != "C'":
            assert abs(row["value"] / row["true"] - 1) < 0.02, row
    assert "Table 3" in rep.report()
    figs = rep.figures()
    assert {"fig5_static_map", "fig7_virgin_curve", "fig10_combined_static", "fig13_revised_gms"} <= set(figs)
    # the JSON embeds the identified models (SI), readable by load_model
    from gmsfric.model_io import model_from_dict

    models = model_from_dict(rep.to_dict())
    assert set(models) == {"static_map", "gms", "plant", "revised_plant_static", "revised_plant_gms"}
    assert isinstance(models["gms"], GMS) and models["gms"] == rep.presliding.model_object
    assert models["plant"].force_gain == presets.paper_plant().force_gain


def _raw_run_csv(tmp_path):
    rig = VirtualRig(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(presets.PaperReading(drive_limit=1e3)), encoder=5e-7, force_noise=1e-3)
    run = rig.constant_velocity_run(np.array([0.05, 0.1, 0.3, 1, 3, 8]) * 1e-3, min_travel=1e-4, max_travel=3e-3, seed=1)
    return _csv(tmp_path / "run.csv", {"t": run["t"], "x": run["position"], "F": run["force"]})


def test_raw_static_map_velocity_unit_only_changes_reporting(tmp_path):
    """--velocity-unit alone never rescales the data: positions stay in --position-unit (m)."""
    f = _raw_run_csv(tmp_path)
    base = ["identify", "static-map", f, "--time", "t", "--position", "x", "--force", "F", "-q"]
    assert main([*base, "--json", str(tmp_path / "si.json")]) == 0
    assert main([*base, "--velocity-unit", "mm/s", "--json", str(tmp_path / "mm.json")]) == 0
    assert main([*base, "--position-unit", "m", "--velocity-unit", "mm/s", "--json", str(tmp_path / "mm2.json")]) == 0
    si, mm, mm2 = (json.loads((tmp_path / n).read_text()) for n in ("si.json", "mm.json", "mm2.json"))
    assert mm["parameters"]["vs"]["value"] == pytest.approx(1e3 * si["parameters"]["vs"]["value"], rel=1e-9)
    assert mm["parameters"]["vs"]["value"] == pytest.approx(mm2["parameters"]["vs"]["value"], rel=1e-12)
    assert mm["units"]["vs"] == "mm/s"
    # the SI model is the same whatever the reporting unit
    assert mm["gmsfric_model"]["parameters"]["vs"]["value"] == pytest.approx(si["gmsfric_model"]["parameters"]["vs"]["value"], rel=1e-6)
    assert mm["gmsfric_model"]["parameters"]["sigma"]["value"] == pytest.approx(si["gmsfric_model"]["parameters"]["sigma"]["value"], rel=1e-6)


def test_raw_static_map_time_unit_with_velocity_unit_reads_the_time_in_it(tmp_path):
    f = tmp_path / "run_ms.csv"
    rig = VirtualRig(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(presets.PaperReading(drive_limit=1e3)), encoder=5e-7, force_noise=1e-3)
    run = rig.constant_velocity_run(np.array([0.05, 0.1, 0.3, 1, 3, 8]) * 1e-3, min_travel=1e-4, max_travel=3e-3, seed=1)
    _csv(f, {"t": run["t"] * 1e3, "x": run["position"] * 1e3, "F": run["force"]})
    out = tmp_path / "o.json"
    assert main(["identify", "static-map", str(f), "--time", "t", "--position", "x", "--force", "F", "--position-unit", "mm", "--time-unit", "ms",
                 "--velocity-unit", "mm/s", "--json", str(out), "-q"]) == 0
    assert json.loads(out.read_text())["gmsfric_model"]["parameters"]["vs"]["value"] == pytest.approx(presets.paper_gms().stribeck.vs, rel=0.1)


def test_raw_static_map_refuses_a_velocity_unit_of_the_other_axis(tmp_path, capsys):
    f = tmp_path / "run.csv"
    f.write_text("t,x,F\n" + "\n".join(f"{i},{i},1" for i in range(60)))
    code = main(["identify", "static-map", str(f), "--time", "t", "--position", "x", "--force", "F", "--velocity-unit", "deg/s"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--velocity-unit 'deg/s'" in err and "--position-unit 'm'" in err and "force" not in err


def test_a_refused_unit_is_not_in_the_expected_list(tmp_path, capsys):
    f = tmp_path / "run.csv"
    f.write_text("t,x,F\n" + "\n".join(f"{i},{i},1" for i in range(60)))
    code = main(["identify", "static-map", str(f), "--time", "t", "--position", "x", "--force", "F", "--position-unit", "deg"])
    err = capsys.readouterr().err
    assert code == 2 and "--force-unit" in err and "expected N m" in err and "expected N," not in err and "force_unit" not in err


@pytest.mark.parametrize("argv, flag", [
    (["presliding", "{f}", "--time", "t", "--position", "x", "--force", "F", "--position-unit", ""], "--position-unit"),
    (["presliding", "{f}", "--time", "t", "--position", "x", "--force", "F", "--position-unit", "deg"], "--force-unit"),
    (["plant", "{f}", "--time", "t", "--input", "x", "--output", "F", "--force-gain", "1", "--force-gain-unit", "N m/V"], "--force-gain-unit"),
    (["static-map", "{f}", "--velocity", "x", "--force", "F", "--force-unit", "N m"], "--force-unit"),
])
def test_unit_errors_name_the_flags_not_python_arguments(tmp_path, capsys, argv, flag):
    f = tmp_path / "run.csv"
    f.write_text("t,x,F\n" + "\n".join(f"{i},{i},1" for i in range(60)))
    assert main(["identify", *[a.format(f=f) for a in argv]]) == 2
    err = capsys.readouterr().err
    assert flag in err and "_unit`" not in err and "`" + flag.strip("-").replace("-", "_") not in err


@pytest.mark.parametrize("argv, units_row, message", [
    (["static-map", "--time", "t", "--position", "x", "--force", "F"], "s,mm,N", "column 'x' is in mm by the file, but --position-unit is 'm'"),
    (["presliding", "--time", "t", "--position", "x", "--force", "F", "--position-unit", "um"], "s,mm,N", "column 'x' is in mm by the file, but --position-unit is 'um'"),
    (["plant", "--time", "t", "--input", "F", "--output", "x", "--fmin", "1", "--fmax", "50"], "ms,m,V", "column 't' is in ms by the file, but --time-unit is 's'"),
])
def test_a_units_row_that_contradicts_the_flags_is_refused(tmp_path, capsys, argv, units_row, message):
    f = tmp_path / "run.csv"
    f.write_text(f"t,x,F\n{units_row}\n" + "\n".join(f"{i * 1e-3},{i * 1e-3},{1.0 + (i % 7)}" for i in range(400)))
    assert main(["identify", argv[0], str(f), *argv[1:]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
