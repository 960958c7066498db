"""The shared result protocol: envelope beside the existing fields, strict JSON, atomic writes."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from matplotlib.figure import Figure

import gmsfric
from gmsfric import io, results
from gmsfric.identify import fit_static_map, static_map_curve
from gmsfric.loop import CATALOGUE, AxisData
from gmsfric.loop.idim import Signals, reference_model
from gmsfric.loop.results import _round_params, parameter_unit


@pytest.fixture(scope="module")
def static_map_result():
    v = np.concatenate([np.geomspace(0.01, 30, 12), -np.geomspace(0.01, 30, 12)])
    F = static_map_curve(v, 0.2, 0.3, 0.5, 0.01, 1.0) + 1e-4 * np.random.default_rng(0).standard_normal(v.size)
    return fit_static_map(v, F, velocity_unit="mm/s", progress=False)


def test_identify_json_keeps_its_fields_and_adds_the_envelope(static_map_result, tmp_path):
    d = static_map_result.to_dict()
    assert d["model"] == "static_map" and list(d["parameters"]) == ["fc", "fs", "vs", "sigma", "delta"]
    assert set(d["parameters"]["fc"]) == {"value", "stderr"} and d["units"]["sigma"] == "N/(mm/s)"
    assert d["schema"] == results.SCHEMA and d["kind"] == "identify.static_map"
    assert d["gmsfric_version"] == gmsfric.__version__ and d["diagnostics"] == []
    assert set(d["provenance"]) >= {"command", "input_files", "columns", "units"}
    text = static_map_result.to_json(tmp_path / "r.json")
    assert json.loads((tmp_path / "r.json").read_text()) == json.loads(text)


def test_plot_is_a_dict_of_figures_and_save_writes_pngs_and_json(static_map_result, tmp_path):
    figs = static_map_result.plot()
    assert figs and all(isinstance(f, Figure) for f in figs.values())
    paths = static_map_result.save(tmp_path / "out")
    names = sorted(p.name for p in paths)
    assert "identify.static_map.json" in names and all(f"{k}.png" in names for k in figs)
    assert not [p for p in (tmp_path / "out").iterdir() if p.name.startswith(".")]  # no temporary files left


def test_jsonable_and_strict_json():
    doc = {"a": np.float64(np.nan), "b": np.arange(3), "c": np.int64(4), "d": (np.inf, 1.5), "e": np.bool_(True)}
    assert json.loads(results.dumps(doc)) == {"a": None, "b": [0, 1, 2], "c": 4, "d": [None, 1.5], "e": True}
    with pytest.raises(ValueError, match="collide"):
        results.envelope("x", {"schema": 1})


def test_atomic_write_replaces_or_leaves_the_target(tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old")
    io.write_text_atomic(target, "new")
    assert target.read_text() == "new"

    class Boom(Exception):
        pass

    with pytest.raises(Boom):
        with io.atomic_path(target) as tmp:
            tmp.write_text("half")
            raise Boom
    assert target.read_text() == "new"  # untouched by the failed write
    assert sorted(os.listdir(tmp_path)) == ["out.json"]
    with pytest.raises(ValueError, match="is a directory"):
        io.write_text_atomic(tmp_path, "x")


def test_every_loop_parameter_has_an_si_unit_linear_and_rotary():
    t = np.arange(4000) * 1e-3
    q = 0.05 * np.sin(2 * np.pi * 0.5 * t) + 0.01 * np.sin(2 * np.pi * 3.1 * t)
    data = AxisData(t, q, 10 * np.sign(np.cos(2 * np.pi * 0.5 * t)) + 1.0, source="synthetic")
    sig = Signals(data)
    r = np.random.default_rng(0).standard_normal(sig.n_rows)
    names = {"delay_s", "sampling_hold_s"}
    for eff in CATALOGUE.values():
        for m in eff.variants(reference_model(), sig, r):
            names.update(m.param_names)
            names.update(h for term in m.terms for h in term.hyper_names)
    missing = sorted(n for n in names if parameter_unit(n) is None)
    assert not missing
    assert parameter_unit("Fv") == "N s/m" and parameter_unit("Fv", rotary=True) == "N m s/rad"
    assert parameter_unit("M", rotary=True) == "kg m^2" and parameter_unit("Delta_block1") == "m"
    p = _round_params({"Fv": {"value": 200.0, "std": 2.0}, "vs": {"value": 0.01, "std": float("nan")}})
    assert p["Fv"] == {"value": 200.0, "std": 2.0, "stderr": 2.0, "unit": "N s/m"}
    assert p["vs"]["std"] is None and p["vs"]["stderr"] is None and p["vs"]["unit"] == "m/s"
