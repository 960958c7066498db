"""Data files: clear DataError naming the problem."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.io import savemat

from gmsfric.errors import DataError
from gmsfric.io import load_columns, read_table


def _csv(path, text):
    path.write_text(text)
    return path


def test_reads_csv_and_mat(tmp_path):
    t = np.arange(20) * 1e-3
    f = _csv(tmp_path / "a.csv", "time,pos\n" + "\n".join(f"{a},{2*a}" for a in t))
    cols = load_columns(f, {"time": "time", "position": "pos"})
    np.testing.assert_allclose(cols["position"], 2 * t)
    savemat(tmp_path / "b.mat", {"t": t[:, None], "q": t[:, None] ** 2, "gain": 35.15})
    tab = read_table(tmp_path / "b.mat")
    assert tab.number("gain") == 35.15 and tab.number("2.5") == 2.5
    np.testing.assert_allclose(load_columns(tab, {"time": "t", "position": "q"})["position"], t**2)


@pytest.mark.parametrize(
    "content, mapping, match",
    [
        ("time,pos\n" + "\n".join(f"{i},{i}" for i in range(20)), {"time": "time", "position": "qm"}, "unknown position column 'qm'; available columns: pos, time"),
        ("", {"time": "time"}, "file is empty"),
        ("time,pos\n", {"time": "time"}, "no data rows"),
        ("time,pos\n1,abc\n2,3\n", {"time": "time"}, "non-numeric value"),
        ("time,pos\n" + "\n".join(f"{i},{i}" for i in range(5)), {"time": "time", "position": "pos"}, "too few samples"),
        ("time,pos\n" + "\n".join(f"{i % 7},{i}" for i in range(20)), {"time": "time", "position": "pos"}, "not strictly increasing at row 7"),
        ("time,pos\n" + "\n".join(f"{i},{'nan' if i == 4 else i}" for i in range(20)), {"time": "time", "position": "pos"}, "non-finite value at row 4"),
        # finite, but squares and sums of them overflow: every fitted number would be nan
        ("time,pos\n" + "\n".join(f"{i},{i}e200" for i in range(20)), {"time": "time", "position": "pos"}, r"column 'pos' \(position\) reaches 1.9e\+201.*check its unit"),
        ("time,pos\n" + "\n".join(f"{i}e-100,{i}" for i in range(20)), {"time": "time", "position": "pos"}, r"time steps down to 1e-100.*units of position and time"),
        ("time,pos\n" + "\n".join(f"{i},{i}e-300" for i in range(20)), {"time": "time", "position": "pos"}, r"column 'pos' \(position\) reaches only 1.9e-299.*underflow"),
    ],
)
def test_bad_files(tmp_path, content, mapping, match):
    f = _csv(tmp_path / "d.csv", content)
    with pytest.raises(DataError, match=match):
        load_columns(f, mapping)


@pytest.mark.parametrize("path", [None, 5, b"\xff"])
def test_a_path_that_is_no_path_is_named(path):
    with pytest.raises(DataError, match="must be a path"):
        load_columns(path, {"time": "t"})


def test_mismatched_lengths_and_missing_file(tmp_path):
    savemat(tmp_path / "m.mat", {"t": np.arange(20.0), "q": np.arange(15.0)})
    with pytest.raises(DataError, match="different lengths"):
        load_columns(tmp_path / "m.mat", {"time": "t", "position": "q"})
    with pytest.raises(DataError, match="no such file"):
        read_table(tmp_path / "nope.csv")
    with pytest.raises(DataError, match="neither a number nor a scalar"):
        read_table(tmp_path / "m.mat").number("gtau")
