"""Data loading for `gmsfric loop`: explicit columns, units, clear errors."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from gmsfric.errors import DataError
from gmsfric.loop import load_axis_data
from gmsfric.units import UnitError


def _csv(path, cols: dict[str, np.ndarray]) -> str:
    names = list(cols)
    rows = np.column_stack([cols[n] for n in names])
    np.savetxt(path, rows, delimiter=",", header=",".join(names), comments="")
    return str(path)


def _run(n: int = 500):
    t = np.arange(n) * 1e-3
    q = 0.01 * np.sin(2 * np.pi * t)
    return t, q, 3.0 * np.cos(2 * np.pi * t)


def test_csv_with_force_and_units(tmp_path):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"time_ms": t * 1e3, "pos_mm": q * 1e3, "F": f})
    d = load_axis_data(p, time="time_ms", position="pos_mm", force="F", time_unit="ms", position_unit="mm")
    assert d.dt == pytest.approx(1e-3)
    np.testing.assert_allclose(d.position, q, atol=1e-12)
    np.testing.assert_allclose(d.force, f)
    assert d.gain is None


def test_mat_with_command_and_gain_by_name_or_number(tmp_path):
    t, q, f = _run()
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:, None], "vir": (f / 2.5)[:, None], "gtau": np.array([[2.5]])})
    d1 = load_axis_data(p, time="t", position="qm", command="vir", gain="gtau")
    d2 = load_axis_data(p, time="t", position="qm", command="vir", gain=2.5)
    np.testing.assert_allclose(d1.force, f)
    np.testing.assert_allclose(d2.force, f)
    assert d1.gain == 2.5


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(force="nope"), "unknown force column 'nope'"),
        (dict(command="F"), "needs a drive gain"),
        (dict(command="F", gain="missing"), "'missing' is neither a number nor a scalar"),
        (dict(force="F", command="F", gain=1.0), "either a force column or a command column"),
        (dict(), "either a force column or a command column"),
    ],
)
def test_bad_column_specs(tmp_path, kwargs, message):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match=message):
        load_axis_data(p, time="t", position="q", **kwargs)


def test_mismatched_lengths(tmp_path):
    t, q, f = _run()
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:-3, None], "F": f[:, None]})
    with pytest.raises(DataError, match="different lengths"):
        load_axis_data(p, time="t", position="qm", force="F")


def test_nan_named(tmp_path):
    t, q, f = _run()
    f[123] = np.nan
    p = tmp_path / "run.mat"
    savemat(p, {"t": t[:, None], "qm": q[:, None], "F": f[:, None]})
    with pytest.raises(DataError, match="non-finite value at row 123"):
        load_axis_data(p, time="t", position="qm", force="F")


def test_non_monotonic_time(tmp_path):
    t, q, f = _run()
    t[200] = t[198]
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match="not strictly increasing at row 200"):
        load_axis_data(p, time="t", position="q", force="F")


def test_too_few_samples(tmp_path):
    t, q, f = _run(50)
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(DataError, match="too few samples"):
        load_axis_data(p, time="t", position="q", force="F")


def test_unknown_unit(tmp_path):
    t, q, f = _run()
    p = _csv(tmp_path / "run.csv", {"t": t, "q": q, "F": f})
    with pytest.raises(UnitError, match="`position_unit`.*unknown unit 'furlong'"):
        load_axis_data(p, time="t", position="q", force="F", position_unit="furlong")
