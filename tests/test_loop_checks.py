"""The loop warns on runs that do not let it identify the axis (and only on those): a force
unrelated to the motion, a run in one direction only, a clipped force; each finding is a
``FitWarning``, stored in the result's diagnostics and printed under the CLI's table."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from gmsfric.cli import main
from gmsfric.errors import FitWarning
from gmsfric.loop import run_loop
from gmsfric.loop.data import AxisData

M, FV, FC = 2.0, 15.0, 3.0


def _axis(position: np.ndarray, t: np.ndarray, seed: int = 0, noise: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and the force of a mass with viscous and Coulomb friction along ``position``."""
    v = np.gradient(position, t)
    force = M * np.gradient(v, t) + FV * v + FC * np.sign(v) + noise * np.random.default_rng(seed).standard_normal(t.size)
    return v, force


def _loop(t, q, f):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FitWarning)
        result = run_loop(AxisData(t, q, f, source="run"))
    return result, [w for w in caught if issubclass(w.category, FitWarning)]


T = np.arange(0.0, 4.0, 1e-3)
SWEEP = 0.01 * np.sin(2 * np.pi * 1.0 * T) + 0.004 * np.sin(2 * np.pi * 3.1 * T)


def test_a_run_the_model_describes_has_no_diagnostics():
    _, f = _axis(SWEEP, T)
    result, caught = _loop(T, SWEEP, f)
    assert result.final.params()["Fc"]["value"] == pytest.approx(FC, rel=0.05)
    assert result.diagnostics == [] and caught == []


def test_a_run_in_one_direction_says_coulomb_and_offset_are_one_number():
    q = 0.03 * T + 0.003 * np.sin(2 * np.pi * 1.5 * T)
    assert np.all(np.diff(q) > 0)
    _, f = _axis(q, T)
    result, caught = _loop(T, q, f)
    pairs = {d["parameter"] for d in result.diagnostics if d["code"] == "degenerate"}
    assert "Fc,offset" in pairs
    assert any("one direction only" in str(w.message) for w in caught)


def test_a_force_unrelated_to_the_motion_is_a_poor_fit():
    f = np.random.default_rng(4).standard_normal(T.size)
    result, caught = _loop(T, SWEEP, f)
    assert result.split.errors_moving(result.final)[0] > 90.0
    assert [d for d in result.diagnostics if d["code"] == "poor_fit"]
    assert any("unexplained" in str(w.message) for w in caught)


def test_a_clipped_force_is_flagged_and_printed_under_the_table(tmp_path, capsys):
    _, f = _axis(SWEEP, T)
    limit = 0.6 * np.abs(f).max()
    f = np.clip(f, -limit, limit)
    path = tmp_path / "clipped.csv"
    np.savetxt(path, np.column_stack([T, SWEEP, f]), delimiter=",", header="t,q,f", comments="")
    assert main(["loop", str(path), "--time", "t", "--position", "q", "--force", "f", "--quiet", "--json", str(tmp_path / "r.json")]) == 0
    out = capsys.readouterr()
    assert "! saturation: force is clipped at its maximum" in out.out and "FitWarning" not in out.err
    saved = json.loads((tmp_path / "r.json").read_text())
    assert any(d["code"] == "saturation" and d["parameter"] == "force" for d in saved["diagnostics"])


@pytest.mark.parametrize(
    "t_scale, q_scale, parameter, message",
    [
        (1e3, 1.0, "time", "sampled at 1 Hz"),  # a 1 kHz log with its time in ms, read as s
        (1.0, 1e4, "position", "moves at up to"),  # positions in units of 0.1 mm, read as m
    ],
)
def test_a_column_in_another_unit_than_declared_is_named(t_scale, q_scale, parameter, message):
    _, f = _axis(SWEEP, T)
    result, caught = _loop(T * t_scale, SWEEP * q_scale, f)
    assert [d for d in result.diagnostics if d["code"] == "units" and d["parameter"] == parameter]
    assert any(message in str(w.message) for w in caught)


def test_a_held_out_run_beyond_the_estimation_travel_is_reported_as_extrapolation():
    _, f = _axis(SWEEP, T)
    wide = 3.0 * SWEEP
    _, f_wide = _axis(wide, T, seed=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", FitWarning)
        result = run_loop(AxisData(T, SWEEP, f, source="est"), AxisData(T, wide, f_wide, source="val"))
    found = [d for d in result.diagnostics if d["code"] == "coverage"]
    assert len(found) == 1 and found[0]["parameter"] == "position"
    lo, hi = result.split.est.q_range
    share = np.mean(np.abs(result.split.val.rows["q"][result.split.val.moving]) > hi)
    assert f"{100 * share:.0f} % of the held-out run" in found[0]["message"]
    assert any("outside the estimation run's travel" in str(w.message) for w in caught)
    # the same travel held out: nothing to report
    _, f_same = _axis(SWEEP, T, seed=2)
    same = run_loop(AxisData(T, SWEEP, f, source="est"), AxisData(T, SWEEP, f_same, source="val"))
    assert not [d for d in same.diagnostics if d["code"] == "coverage"]
