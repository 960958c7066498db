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
        ("time,pos\n1,abc\n2,3\n", {"time": "time"}, "data row 1, column 'pos': 'abc' is not a number"),
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


def _log(n=300):
    t = np.arange(n) * 1e-2
    q = np.column_stack([np.zeros(n), np.sin(t), 0.5 * t])
    return t, q


def test_mat_structs_and_matrices_are_named_as_in_matlab(tmp_path):
    t, q = _log()
    savemat(tmp_path / "log.mat", {"log": {"t": t, "q": q, "joint": {"kt": 1.7, "tau": q.T}}, "label": "run 3"})
    tab = read_table(tmp_path / "log.mat")
    cols = load_columns(tab, {"time": "log.t", "position": "log.q(:,2)", "force": "log.joint.tau(3,:)"})
    np.testing.assert_array_equal(cols["time"], t)
    np.testing.assert_array_equal(cols["position"], q[:, 1])
    np.testing.assert_array_equal(cols["force"], q[:, 2])  # a wide matrix holds its signals in rows
    np.testing.assert_array_equal(tab.column("log.q(:, 2)"), q[:, 1])  # spaced as one may type it
    assert tab.number("log.joint.kt") == 1.7
    with pytest.raises(DataError, match=r"'log.q' is a 300x3 matrix; name one of its signals, e.g. log.q\(:,1\)"):
        tab.column("log.q", "position")
    with pytest.raises(DataError, match=r"'log.q\(:,4\)'; available columns: .*log.q\(:,3\)"):
        tab.column("log.q(:,4)", "position")


def test_a_mat_file_without_signals_says_what_it_holds(tmp_path):
    savemat(tmp_path / "text.mat", {"name": "axis 2", "cells": np.array([np.arange(3.0), np.arange(4.0)], dtype=object),
                                    "z": np.arange(3) + 1j})
    with pytest.raises(DataError, match=r"no numeric vectors in the file \(not read: .*cells.*z"):
        read_table(tmp_path / "text.mat")


def _save_mat73(path, variables):
    """A file laid out as MATLAB's ``save -v7.3`` writes it: HDF5 behind a 512-byte header,
    arrays transposed (column-major), structs as groups."""
    h5py = pytest.importorskip("h5py")

    def put(group, name, value):
        if isinstance(value, dict):
            sub = group.create_group(name)
            sub.attrs["MATLAB_class"] = np.bytes_("struct")
            for k, v in value.items():
                put(sub, k, v)
        elif isinstance(value, str):
            ds = group.create_dataset(name, data=np.frombuffer(value.encode("utf-16-le"), dtype=np.uint16)[:, None])
            ds.attrs["MATLAB_class"] = np.bytes_("char")
        else:
            ds = group.create_dataset(name, data=np.atleast_2d(np.asarray(value, dtype=float)).T)
            ds.attrs["MATLAB_class"] = np.bytes_("double")

    with h5py.File(path, "w", userblock_size=512) as fh:
        for k, v in variables.items():
            put(fh, k, v)
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Sat Nov 28 12:00:00 2026 HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(header.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02" + b"IM")


def test_mat_v73_files_are_read_like_older_ones(tmp_path):
    t, q = _log()
    _save_mat73(tmp_path / "v73.mat", {"t": t[:, None], "q": q, "s": {"gain": np.array([[2.5]]), "name": "joint 2"}})
    savemat(tmp_path / "v7.mat", {"t": t[:, None], "q": q, "s": {"gain": 2.5, "name": "joint 2"}})
    new, old = read_table(tmp_path / "v73.mat"), read_table(tmp_path / "v7.mat")
    assert sorted(new.columns) == sorted(old.columns) == ["q(:,1)", "q(:,2)", "q(:,3)", "t"]
    for name in old.columns:
        np.testing.assert_array_equal(new.column(name), old.column(name))
    assert new.scalars == old.scalars == {"s.gain": 2.5}


def test_mat_v73_without_h5py_says_how_to_read_it(tmp_path, monkeypatch):
    t, q = _log()
    _save_mat73(tmp_path / "v73.mat", {"t": t[:, None]})
    monkeypatch.setitem(__import__("sys").modules, "h5py", None)  # import h5py now fails
    with pytest.raises(DataError, match=r"MATLAB -v7.3 \(HDF5\) file; install h5py .* '-v7'"):
        read_table(tmp_path / "v73.mat")


def _rows(n=30):
    return "\n".join(f"{i * 1e-3},{0.5 * i},{2.0 - i}" for i in range(n))


def test_csv_preamble_comments_and_a_decimal_comma_are_read(tmp_path):
    plain = load_columns(_csv(tmp_path / "a.csv", "t,q,f\n" + _rows()), {"time": "t", "position": "q", "force": "f"})
    commented = _csv(tmp_path / "b.csv", "# rig 3, joint 2\n% logged at 1 kHz\nt,q,f\n" + _rows())
    semicolons = _csv(tmp_path / "c.csv", "t;q;f\n" + _rows().replace(",", ";").replace(".", ","))
    for path in (commented, semicolons):
        cols = load_columns(path, {"time": "t", "position": "q", "force": "f"})
        for role in plain:
            np.testing.assert_allclose(cols[role], plain[role], rtol=0, atol=1e-15)


@pytest.mark.parametrize("content, match", [
    ("0.0,1.0,2.0\n" + _rows(), r"first row holds numbers, not column names; add a header row"),
    ("# logged on rig 3\n" + _rows(), r"first row holds numbers, not column names"),  # a note is no header
    ("t,q,f\n" + _rows(5) + "\n0.006,,1\n" + _rows(5), r"data row 6, column 'q': empty"),
    ("t,q,f\n" + _rows(5) + "\n0.006,n/a,1\n", r"data row 6, column 'q': 'n/a' is not a number"),
    ("t,q,f\n" + _rows(5) + "\n0.006,1\n", r"data row 6 has 2 fields, the header 3"),
])
def test_csv_faults_name_the_column_and_row(tmp_path, content, match):
    with pytest.raises(DataError, match=match):
        read_table(_csv(tmp_path / "d.csv", content))


@pytest.mark.parametrize("units_row", ["s,mm,N", "[s],[mm],[N]", "(s),(mm),(N)"])
def test_a_units_row_must_agree_with_the_declared_units(tmp_path, units_row):
    path = _csv(tmp_path / "u.csv", f"t,q,f\n{units_row}\n" + _rows())
    mapping = {"time": "t", "position": "q", "force": "f"}
    declared = {"time": ("s", "time", "time_unit"), "force": ("N", "force", "force_unit")}
    cols = load_columns(path, mapping, declared_units={**declared, "position": ("mm", "position", "position_unit")})
    np.testing.assert_allclose(cols["position"], 0.5 * np.arange(30))  # the units row is not data
    with pytest.raises(DataError, match=r"column 'q' is in mm by the file, but `position_unit` is 'm' "
                                        r"\(the values would be off by a factor 0.001\); declare it as mm"):
        load_columns(path, mapping, declared_units={**declared, "position": ("m", "position", "position_unit")})


def test_a_units_row_gmsfric_cannot_read_is_refused_and_a_blank_unit_is_not_checked(tmp_path):
    path = _csv(tmp_path / "u.csv", "t,q,f\ns,counts,-\n" + _rows())
    declared = {"position": ("m", "position", "position_unit"), "force": ("kN", "force", "force_unit")}
    with pytest.raises(DataError, match=r"column 'q' is labelled 'counts' in the file's units row, a unit gmsfric cannot read"):
        load_columns(path, {"time": "t", "position": "q"}, declared_units=declared)
    assert load_columns(path, {"time": "t", "force": "f"}, declared_units=declared)["force"].size == 30


def test_a_commented_header_right_above_the_data_names_the_columns(tmp_path):
    t = np.arange(30) * 1e-3
    np.savetxt(tmp_path / "np.csv", np.column_stack([t, t**2]), delimiter=",", header="t,q")  # writes "# t,q"
    (tmp_path / "ros.csv").write_text("%time,field.position0\n" + "\n".join(f"{1732800000000000000 + i * 10**7},{0.1 * i}" for i in range(30)))
    (tmp_path / "notes.csv").write_text("# a note\nt,q\n# a remark inside the data\n" + "\n".join(f"{a},{a * a}" for a in t))
    (tmp_path / "matlab.csv").write_text("t,q\n" + "\n".join(f"{a},{a * a}" for a in t[:10]) + "\n% paused\n" + "\n".join(f"{a},{a * a}" for a in t[10:]))
    np.testing.assert_array_equal(read_table(tmp_path / "matlab.csv").column("q"), t**2)
    np.testing.assert_allclose(read_table(tmp_path / "np.csv").column("q"), t**2)
    np.testing.assert_allclose(np.diff(read_table(tmp_path / "ros.csv").column("time")), 1e7, rtol=1e-4)  # ns since 1970 in doubles: 256 ns steps
    np.testing.assert_allclose(read_table(tmp_path / "notes.csv").column("q"), t**2)


def test_a_unit_at_the_end_of_a_column_name_is_checked_too(tmp_path):
    path = _csv(tmp_path / "h.csv", "t [s],x (mm),F (filtered)\n" + _rows())
    mapping = {"time": "t [s]", "position": "x (mm)", "force": "F (filtered)"}
    declared = {"time": ("s", "time", "time_unit"), "force": ("kN", "force", "force_unit")}
    cols = load_columns(path, mapping, declared_units={**declared, "position": ("mm", "position", "position_unit")})
    assert cols["position"].size == 30  # "(filtered)" is no unit: the force is taken as declared
    with pytest.raises(DataError, match=r"column 'x \(mm\)' is in mm by the file, but `position_unit` is 'um'"):
        load_columns(path, mapping, declared_units={**declared, "position": ("um", "position", "position_unit")})


def test_a_time_column_of_date_stamps_is_read_as_seconds(tmp_path):
    stamps = [f"2026-11-28 23:59:59.{k:03d}" for k in range(990, 1000)] + [f"2026-11-29T00:00:00.{k:03d}Z" for k in range(20)]
    path = _csv(tmp_path / "s.csv", "stamp,q\n" + "\n".join(f"{s},{i}" for i, s in enumerate(stamps)))
    mapping = {"time": "stamp", "position": "q"}
    cols = load_columns(path, mapping, declared_units={"time": ("s", "time", "time_unit")})
    np.testing.assert_allclose(cols["time"], np.arange(30) * 1e-3, atol=1e-12)  # across midnight
    with pytest.raises(DataError, match=r"column 'stamp' is in s by the file, but `time_unit` is 'ms'"):
        load_columns(path, mapping, declared_units={"time": ("ms", "time", "time_unit")})
    broken = _csv(tmp_path / "b.csv", "stamp,q\n2026-11-28 12:00:00.000,0\nlater,1\n")
    with pytest.raises(DataError, match=r"data row 2, column 'stamp': 'later' is not a date and time like the first row's"):
        read_table(broken)
