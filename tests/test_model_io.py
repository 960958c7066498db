"""save_model / load_model: every model kind round-trips; identify JSONs in any unit load as the
SI model; legacy files are converted with the unit table; nothing is read with a factor of 1."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

import gmsfric as g
from gmsfric import InvalidInputError, model_io, presets
from gmsfric.identify import VirtualRig, estimate_frf, fit_plant, fit_presliding, fit_static_map, static_map_curve
from gmsfric.model_io import ModelFormatError, load_model, load_model_document, save_model
from gmsfric.units import UnitError

ST = g.Stribeck(0.18, 0.21, 4.5e-4, 1.3)
MODELS = [
    g.StaticFriction(ST, sigma=6.98, offset=-0.3, v_linear=1e-4),
    presets.paper_gms(),
    g.GMS(ST, [2e6, 3e4], [0.3, 0.7], 25.0, 1.5, slip_law="displacement"),
    g.MaxwellSlip([3.2e6, 8.9e3], [0.033, 0.057], sigma=0.5),
    g.LuGre(ST, 1e5, 3.0, 0.7),
    g.Plant(0.01985, 168.4, 176.8, 1.29e-3, 35.0),
]


def _rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize("rotary", [False, True])
def test_every_kind_round_trips_exactly(model, rotary, tmp_path):
    model = dataclasses.replace(model, rotary=rotary)
    p = save_model(model, tmp_path / "m.json", provenance={"note": "test"})
    doc = json.loads(p.read_text())
    assert doc["schema"] == "gmsfric.model/1" and doc["gmsfric_version"] == g.__version__
    assert doc["axis"] == ("rotary" if rotary else "linear") and doc["provenance"] == {"note": "test"}
    assert all(set(v) == {"value", "unit"} for v in doc["parameters"].values())
    back = load_model(p)
    assert back == model and back.rotary is rotary
    # saved again as loaded: the same document (the axis is never lost on the way)
    again = json.loads(save_model(back, tmp_path / "m2.json", rotary=rotary, provenance={"note": "test"}).read_text())
    assert again == doc


@pytest.mark.parametrize("model", MODELS, ids=lambda m: type(m).__name__)
def test_save_model_refuses_to_relabel_a_model_of_the_other_axis(model, tmp_path):
    with pytest.raises(InvalidInputError, match="`rotary`=True would relabel `model`, a linear-axis model"):
        save_model(model, tmp_path / "m.json", rotary=True)
    with pytest.raises(InvalidInputError, match="`rotary`=False would relabel `model`, a rotary-axis model"):
        save_model(dataclasses.replace(model, rotary=True), tmp_path / "m.json", rotary=False)
    assert not (tmp_path / "m.json").exists()


def test_a_rotary_identification_gives_a_rotary_model_in_python_and_in_its_file(tmp_path):
    v = np.concatenate([np.geomspace(0.01, 30, 14), -np.geomspace(0.01, 30, 14)])  # deg/s
    F = static_map_curve(v, 0.2, 0.3, 0.5, 0.01, 1.0)
    res = fit_static_map(v, F, velocity_unit="deg/s", force_unit="N m", progress=False)
    assert res.model_object.rotary is True
    p = tmp_path / "r.json"
    p.write_text(res.to_json())
    back = load_model(p)
    assert isinstance(back, g.StaticFriction) and back.rotary is True and back == res.model_object
    assert json.loads(save_model(back, tmp_path / "again.json").read_text())["parameters"]["fc"]["unit"] == "N m"


def test_units_in_the_document_are_converted_and_checked(tmp_path):
    doc = model_io.model_to_dict(g.StaticFriction(ST, sigma=7.0))
    doc["parameters"]["sigma"] = {"value": 7e-3, "unit": "N/(mm/s)"}
    doc["parameters"]["vs"] = {"value": 0.45, "unit": "mm/s"}
    (tmp_path / "a.json").write_text(json.dumps(doc))
    m = load_model(tmp_path / "a.json")
    assert _rel(m.sigma, 7.0) < 1e-12 and _rel(m.stribeck.vs, 4.5e-4) < 1e-12
    doc["parameters"]["sigma"]["unit"] = "N/(furlong/s)"
    (tmp_path / "b.json").write_text(json.dumps(doc))
    with pytest.raises(UnitError, match="b.json.*unknown unit 'furlong'"):
        load_model(tmp_path / "b.json")
    doc["parameters"]["sigma"]["unit"] = "N/mm"  # a stiffness, not a damping
    (tmp_path / "c.json").write_text(json.dumps(doc))
    with pytest.raises(UnitError, match="not a damping unit"):
        load_model(tmp_path / "c.json")


@pytest.fixture(scope="module")
def static_map_data():
    v = np.concatenate([np.geomspace(0.01, 30, 14), -np.geomspace(0.01, 30, 14)])  # mm/s
    F = static_map_curve(v, 0.2, 0.3, 0.5, 0.01, 1.0) + 1e-4 * np.random.default_rng(0).standard_normal(v.size)  # N
    return v, F


def test_static_map_in_mm_s_and_mN_round_trips_to_the_si_fit(static_map_data, tmp_path):
    v, F = static_map_data
    res = fit_static_map(v, F * 1e3, velocity_unit="mm/s", force_unit="mN", progress=False)
    assert res.units["sigma"] == "mN/(mm/s)"
    si = res.model_object
    assert isinstance(si, g.StaticFriction)
    assert _rel(si.stribeck.vs, res.value("vs") * 1e-3) < 1e-12 and _rel(si.sigma, res.value("sigma")) < 1e-12  # mN/(mm/s) = N s/m
    res.to_json(tmp_path / "r.json")
    assert load_model(tmp_path / "r.json") == si
    # the same data given in SI fit to the same model (the fit is scale-invariant)
    ref = fit_static_map(v * 1e-3, F, progress=False).model_object
    for a, b in ((si.stribeck.fc, ref.stribeck.fc), (si.stribeck.fs, ref.stribeck.fs), (si.stribeck.vs, ref.stribeck.vs), (si.sigma, ref.sigma)):
        assert _rel(a, b) < 1e-6
    # a legacy file (no embedded model) is converted with the unit table to the same model
    legacy = json.loads((tmp_path / "r.json").read_text())
    for k in ("gmsfric_model", "schema", "kind"):
        legacy.pop(k)
    (tmp_path / "legacy.json").write_text(json.dumps(legacy))
    m = load_model(tmp_path / "legacy.json")
    for a, b in ((m.stribeck.fc, si.stribeck.fc), (m.stribeck.vs, si.stribeck.vs), (m.sigma, si.sigma), (m.stribeck.delta, si.stribeck.delta)):
        assert _rel(a, b) < 1e-12


def test_covariance_is_stored_in_si_and_matches_the_standard_errors(static_map_data, tmp_path):
    v, F = static_map_data
    res = fit_static_map(v, F, velocity_unit="mm/s", progress=False)
    names, cov = res.covariance
    assert names == ["fc", "fs", "vs", "sigma", "delta"]
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), [res.stderr(n) for n in names], rtol=1e-10)
    res.to_json(tmp_path / "r.json")
    doc = load_model_document(tmp_path / "r.json")
    c = doc["covariance"]
    assert c["names"] == names and c["units"] == ["N", "N", "m/s", "N s/m", "1"]
    se_si = np.sqrt(np.diag(np.array(c["matrix"], dtype=float)))
    np.testing.assert_allclose(se_si, [res.stderr("fc"), res.stderr("fs"), res.stderr("vs") * 1e-3, res.stderr("sigma") * 1e3, res.stderr("delta")], rtol=1e-10)


@pytest.fixture(scope="module")
def presliding_record():
    gms = g.GMS.from_break_forces([1e6, 1e5], [1.0, 2.0], 1e5)
    return VirtualRig(g.Plant(1.0, 0, 0), gms, g.PID(0.0), encoder=1e-9, force_noise=1e-3).sinusoid_test([2e-6, 1e-4], 0.5, cycles=2, seed=0)


def test_presliding_in_mN_and_um_round_trips(presliding_record, tmp_path):
    d = presliding_record
    res = fit_presliding(d["t"], d["position"] * 1e6, d["force"] * 1e3, n_blocks=2, position_unit="um", force_unit="mN", progress=False)
    assert res.units["k1"] == "mN/um"
    gms = res.model_object
    assert isinstance(gms, g.GMS)
    k_si = sorted(gms.k)
    assert _rel(k_si[0], 1e5) < 0.03 and _rel(k_si[1], 1e6) < 0.03  # N/m, not mN/um read as N/m (1000x off)
    assert _rel(sorted(gms.break_forces)[0], 1.0) < 0.03
    names, cov = res.covariance
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), [res.stderr(n) for n in names], rtol=1e-10)
    res.to_json(tmp_path / "p.json")
    back = load_model(tmp_path / "p.json")
    assert back == gms
    legacy = {k: v for k, v in json.loads((tmp_path / "p.json").read_text()).items() if k in ("model", "parameters", "units")}
    (tmp_path / "legacy.json").write_text(json.dumps(legacy))
    ms = load_model(tmp_path / "legacy.json")
    assert isinstance(ms, g.MaxwellSlip)
    for a, b in zip(ms.k, gms.k):
        assert _rel(a, b) < 1e-12
    for a, b in zip(ms.w, gms.break_forces):
        assert _rel(a, b) < 1e-12


@pytest.fixture(scope="module")
def frf():
    d = VirtualRig(presets.paper_plant(), None, g.PID(0.0), dt=5e-4).noise_test(4.0, 5.0, (0.5, 300.0), seed=0)
    return estimate_frf(d["t"], d["input"], d["output"])


def test_plant_needs_a_force_gain_to_load(frf, tmp_path):
    res = fit_plant(frf, fmin=1.0, fmax=300.0, force_gain=35.0)
    res.to_json(tmp_path / "p.json")
    p = load_model(tmp_path / "p.json")
    assert isinstance(p, g.Plant) and p.force_gain == 35.0 and p == res.model_object
    assert _rel(p.delay, 1.29e-3) < 0.05
    names, cov = res.covariance
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), [res.stderr(n) for n in names], rtol=1e-10)
    bare = fit_plant(frf, fmin=1.0, fmax=300.0)
    bare.to_json(tmp_path / "bare.json")
    with pytest.raises(ModelFormatError, match="no force gain.*--force-gain"):
        load_model(tmp_path / "bare.json")
    # the same FRF and record with the output in mm (fit_plant also uses the record the FRF came from)
    in_mm = dataclasses.replace(frf, H=frf.H * 1e3, record=dataclasses.replace(frf.record, output=frf.record.output * 1e3))
    mm = fit_plant(in_mm, fmin=1.0, fmax=300.0, output_unit="mm", force_gain=35e3, force_gain_unit="mN/V")
    mm.to_json(tmp_path / "mm.json")
    q = load_model(tmp_path / "mm.json")
    assert _rel(q.a, res.model_object.a) < 1e-6 and _rel(q.force_gain, 35.0) < 1e-12


def test_bundle_part_and_errors(tmp_path):
    save_model({"static_map": MODELS[0], "plant": MODELS[-1]}, tmp_path / "b.json")
    both = load_model(tmp_path / "b.json")
    assert both == {"static_map": MODELS[0], "plant": MODELS[-1]}
    assert load_model(tmp_path / "b.json", part="plant") == MODELS[-1]
    with pytest.raises(ModelFormatError, match="no model 'gms'"):
        load_model(tmp_path / "b.json", part="gms")


@pytest.mark.parametrize(
    "content, match",
    [
        ("not json", "not JSON"),
        ("[1, 2]", "expected a JSON object"),
        ("{}", "not a gmsfric model document"),
        ('{"model": "static_map", "parameters": {"fc": {"value": 0.1}, "fs": 0.2, "vs": 1e-3, "sigma": 1, "delta": 1}}', "no unit stated for 'vs'"),
        ('{"model": "static_map", "parameters": {"fc": 1, "fs": 1, "vs": 1, "sigma": 1, "delta": 1}, "units": {"fc": "N", "fs": "N", "vs": "mm/s", "sigma": "N s/mm", "delta": "1"}}', None),
        ('{"model": "static_map", "parameters": {"fc": 1, "fs": 1, "vs": 1, "sigma": 1, "delta": 1}, "units": {"fc": "mm", "fs": "N", "vs": "mm/s", "sigma": "N s/mm", "delta": "1"}}', "not a force unit"),
        ('{"model": "plant", "parameters": {"a": 1, "b": 1, "c": 1, "delay": 0.001}, "units": {"a": "mm/(V s^2)", "b": "1/s", "c": "1/s^2", "delay": "s"}}', "no force gain"),
        ('{"schema": "gmsfric.model/9", "kind": "plant"}', "unsupported model schema"),
        ('{"schema": "gmsfric.model/1", "kind": "spring"}', "unknown model kind 'spring'"),
        ('{"schema": "gmsfric.model/1", "kind": "maxwell_slip", "parameters": {"k": {"value": [1e6], "unit": "N/m"}}}', "'w' is missing"),
        ('{"schema": "gmsfric.model/1", "kind": "maxwell_slip", "parameters": {"k": {"value": [-1e6], "unit": "N/m"}, "w": {"value": [1], "unit": "N"}}}', "invalid maxwell_slip parameters"),
        ('{"schema": "gmsfric.model/1", "kind": "maxwell_slip", "parameters": {"k": {"value": [1e6], "unit": "N/m"}, "w": {"value": [1], "unit": "N"}, "q": {"value": 1, "unit": "1"}}}', "unknown maxwell_slip parameter"),
        ('{"schema": "gmsfric.result/1", "kind": "loop", "final": {}, "baseline": {}}', "register_result_reader"),
    ],
)
def test_bad_files_are_errors_never_a_factor_of_one(tmp_path, content, match):
    f = tmp_path / "m.json"
    f.write_text(content)
    if match is None:
        m = load_model(f)
        assert _rel(m.stribeck.vs, 1e-3) < 1e-12 and _rel(m.sigma, 1e3) < 1e-12
        return
    with pytest.raises(InvalidInputError, match=match):
        load_model(f)


def test_registry_accepts_new_kinds_and_result_readers(tmp_path):
    class Spring:
        def __init__(self, k):
            self.k = k

    model_io.register_kind("test_spring", Spring, lambda s: ({"k": (s.k, "stiffness")}, {}), lambda p: Spring(p.get("k", "stiffness")), replace=True)
    save_model(Spring(2.5e6), tmp_path / "s.json")
    assert load_model(tmp_path / "s.json").k == 2.5e6
    model_io.register_result_reader("test_result", lambda doc, src: Spring(doc["k"]), replace=True)
    (tmp_path / "r.json").write_text(json.dumps({"schema": "gmsfric.result/1", "kind": "test_result", "k": 3.0}))
    assert load_model(tmp_path / "r.json").k == 3.0
    with pytest.raises(InvalidInputError, match="already registered"):
        model_io.register_kind("gms", Spring, None, None)


def test_toplevel_api():
    assert g.save_model is save_model and g.load_model is load_model
