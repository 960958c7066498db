"""`gmsfric glitch` on the command line: one axis kind per study (an angle is never a length),
rotary studies reported in angles, a saturated drive reported, settings refused before any work."""

from __future__ import annotations

import dataclasses
import json

import pytest

from gmsfric import presets
from gmsfric.cli import main
from gmsfric.model_io import save_model

FAST = ["--dt", "2e-3", "--frequency", "0.05"]


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    d = tmp_path_factory.mktemp("glitch_models")
    rot = lambda m: dataclasses.replace(m, rotary=True)  # noqa: E731
    save_model(presets.paper_plant(), d / "plant.json")
    save_model(rot(presets.paper_plant()), d / "plant_rot.json")
    save_model(presets.paper_static_friction(), d / "static.json")
    save_model(rot(presets.paper_static_friction()), d / "static_rot.json")
    save_model(rot(presets.paper_gms()), d / "gms_rot.json")
    return d


def _one_line_error(capsys, code, *parts):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    for p in parts:
        assert p in err[0], err[0]


@pytest.mark.parametrize("argv, parts", [
    (["--plant", "{d}/plant_rot.json", "--friction", "{d}/static.json"], ("plant_rot.json is of a rotary axis", "static.json of a linear one")),
    (["--plant", "{d}/plant.json", "--friction", "{d}/static_rot.json", "--friction", "{d}/gms_rot.json"], ("is of a linear axis", "of a rotary one")),
    (["--plant", "{d}/plant_rot.json"], ("the default friction (the paper's, linear)",)),
    (["--friction", "{d}/static_rot.json", "--friction", "{d}/gms_rot.json"], ("the default plant (the paper's, linear)",)),
    (["--friction", "{d}/static.json", "--friction", "{d}/gms_rot.json"], ("`--friction` files of different axes",)),
    (["--plant", "{d}/plant_rot.json", "--friction", "{d}/static_rot.json"], ("pre-sliding blocks missing",)),
])
def test_glitch_refuses_to_mix_rotary_and_linear_models(models, argv, parts, tmp_path, capsys):
    out = tmp_path / "g.json"
    assert main(["glitch", *[a.format(d=models) for a in argv], *FAST, "--json", str(out)]) == 2
    _one_line_error(capsys, 2, *parts)
    assert not out.exists()


def test_a_rotary_study_reports_its_glitches_in_angles(models, tmp_path, capsys):
    out = tmp_path / "g.json"
    argv = ["glitch", "--plant", str(models / "plant_rot.json"), "--friction", str(models / "static_rot.json"),
            "--friction", str(models / "gms_rot.json"), *FAST, "--json", str(out)]
    assert main(argv) == 0
    assert "sinusoid peak glitch [µrad]" in capsys.readouterr().err
    doc = json.loads(out.read_text())
    assert doc["parameters"]["axis"] == "rotary" and doc["parameters"]["position_unit"] == "rad"
    assert "amplitude_rad" in doc["parameters"] and "amplitude_m" not in doc["parameters"]
    assert "peak_error_rad" in doc["sinusoid"]["gms"] and "peak_error_m" not in doc["sinusoid"]["gms"]
    assert "radius_rad" in doc["circle"] and "peak_glitch_rad" in doc["circle"]["gms"]
    assert doc["provenance"]["units"]["amplitude"] == "rad" and doc["provenance"]["units"]["kp"] == "V/rad"
    # the same numbers as the linear study of the same models
    lin = tmp_path / "lin.json"
    assert main(["glitch", "--plant", str(models / "plant.json"), *FAST, "--json", str(lin), "-q"]) == 0
    ld = json.loads(lin.read_text())
    assert ld["parameters"]["axis"] == "linear" and "peak_error_m" in ld["sinusoid"]["gms"]
    assert doc["sinusoid"]["gms"]["peak_error_rad"] == pytest.approx(ld["sinusoid"]["gms"]["peak_error_m"], rel=1e-9)


def test_a_saturated_drive_is_a_diagnostic(tmp_path, capsys):
    out = tmp_path / "g.json"
    assert main(["glitch", *FAST, "--amplitude", "1", "--json", str(out)]) == 0
    assert "! saturation: the drive is at its limit (100 V)" in capsys.readouterr().err
    doc = json.loads(out.read_text())
    (d,) = [d for d in doc["diagnostics"] if d["code"] == "saturation"]
    assert d["fraction"] > 0.05 and doc["saturation"]["max_fraction"] == d["fraction"]
    ok = tmp_path / "ok.json"
    assert main(["glitch", *FAST, "--json", str(ok), "-q"]) == 0
    doc = json.loads(ok.read_text())
    assert doc["diagnostics"] == [] and doc["saturation"]["max_fraction"] < 0.01 and doc["saturation"]["drive_limit"] == 100.0


@pytest.mark.parametrize("argv, parts", [
    (["--table3", "--plant", "{d}/plant.json"], ("--table3", "does not go with --plant FILE")),
    (["--dt", "10"], ("--dt 10 s gives 10 steps per period",)),
    (["--dt", "0.01", "--frequency", "20"], ("--dt 0.01 s gives 5 steps per period",)),
    (["--dt", "0.04", "--frequency", "0.01"], ("--dob-cutoff 20 Hz must lie below the Nyquist frequency 12.5 Hz",)),
])
def test_glitch_settings_are_refused_before_any_work(models, argv, parts, capsys):
    assert main(["glitch", *[a.format(d=models) for a in argv]]) == 2
    _one_line_error(capsys, 2, *parts)


def test_glitch_names_an_axis_model_for_what_it_is(tmp_path, capsys):
    from gmsfric import AxisModel, AxisUnits, Effects

    m = AxisModel(presets.paper_plant(), presets.paper_static_friction(), Effects(), AxisUnits("linear", "V"))
    save_model(m, tmp_path / "axis.json")
    for option in ("--plant", "--friction"):
        assert main(["glitch", option, str(tmp_path / "axis.json")]) == 2
        _one_line_error(capsys, 2, f"`{option}` {tmp_path / 'axis.json'} is an axis model (the JSON of `gmsfric loop`)", f"{option} needs")
