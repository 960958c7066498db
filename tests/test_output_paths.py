"""Output paths: a regular file is replaced atomically; a symbolic link is written through; a
device or FIFO is written in place (never replaced); errors name the user's path, never a
temporary file; `--json -` is standard output for every command.  No real /dev node is used."""

from __future__ import annotations

import json
import os
import threading

import numpy as np
import pytest

from gmsfric import OutputPathError, presets
from gmsfric.cli import main
from gmsfric.io import write_text_atomic
from gmsfric.model_io import load_model, save_model


def _reader(path, sink, close_at_once=False):
    def run():
        with open(path, "rb") as fh:
            if not close_at_once:
                sink.append(fh.read())

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs")
def test_a_fifo_target_is_written_in_place_never_replaced(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    th = _reader(fifo, got)
    write_text_atomic(fifo, "hello\n")
    th.join(5)
    assert got == [b"hello\n"]
    assert fifo.is_fifo() and sorted(os.listdir(tmp_path)) == ["pipe"]  # no temp file left, the node is still a FIFO


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs")
def test_a_write_error_on_a_fifo_is_an_error_naming_the_path(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    th = _reader(fifo, [], close_at_once=True)
    with pytest.raises(OSError) as info:
        write_text_atomic(fifo, "x" * (1 << 20))  # more than a pipe buffer: the closed reader breaks it
    th.join(5)
    assert str(fifo) in str(info.value) and ".tmp" not in str(info.value)
    assert fifo.is_fifo()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs")
def test_cli_json_into_a_fifo(tmp_path, capsys):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    th = _reader(fifo, got)
    assert main(["glitch", "--dt", "2e-3", "--frequency", "0.05", "--json", str(fifo), "-q"]) == 0
    th.join(5)
    assert json.loads(got[0])["kind"] == "glitch" and fifo.is_fifo()


def test_a_symlink_is_written_through_to_its_target(tmp_path):
    real = tmp_path / "real.json"
    real.write_text("old")
    link = tmp_path / "link.json"
    link.symlink_to(real)
    save_model(presets.paper_gms(), link)
    assert link.is_symlink() and os.readlink(link) == str(real)
    assert load_model(real) == presets.paper_gms()
    assert sorted(os.listdir(tmp_path)) == ["link.json", "real.json"]


@pytest.mark.parametrize("target, message", [
    ("{d}", "`path` {d}: is a directory"),
    ("{d}/missing/x.json", "`path` {d}/missing/x.json: directory {d}/missing does not exist"),
    ("{d}/newdir/", "ends with '/'"),
    ("", "must be a file name"),
])
def test_save_model_names_the_users_path_never_a_temp_file(tmp_path, target, message):
    with pytest.raises(OutputPathError) as info:
        save_model(presets.paper_gms(), target.format(d=tmp_path))
    assert isinstance(info.value, ValueError)
    assert message.format(d=tmp_path) in str(info.value) and ".tmp" not in str(info.value)
    assert sorted(os.listdir(tmp_path)) == []


def test_a_file_in_a_directory_without_write_permission_names_the_path(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    d = tmp_path / "ro"
    d.mkdir()
    d.chmod(0o500)
    try:
        with pytest.raises(OSError) as info:
            save_model(presets.paper_gms(), d / "m.json")
        assert str(d / "m.json") in str(info.value) and ".tmp" not in str(info.value)
    finally:
        d.chmod(0o700)


def _static_csv(tmp_path):
    v = np.concatenate([np.geomspace(0.01, 30, 14), -np.geomspace(0.01, 30, 14)])
    F = np.sign(v) * (0.2 + 0.1 * np.exp(-np.abs(v) / 0.5)) + 0.01 * v
    f = tmp_path / "map.csv"
    np.savetxt(f, np.column_stack([v, F]), delimiter=",", header="vel,F", comments="")
    return str(f)


def test_json_dash_is_stdout_for_identify(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    f = _static_csv(tmp_path)
    assert main(["identify", "static-map", f, "--velocity", "vel", "--force", "F", "--velocity-unit", "mm/s", "--json", "-"]) == 0
    cap = capsys.readouterr()
    assert json.loads(cap.out)["model"] == "static_map"  # stdout holds the JSON alone
    assert "parameter" in cap.err
    assert not (tmp_path / "-").exists()


@pytest.mark.parametrize("target, message", [
    ("newdir/", "--json newdir/: ends with '/'"),
    ("missing/x.json", "--json missing/x.json: directory missing does not exist"),
])
def test_cli_refuses_a_directory_name_before_any_work(tmp_path, capsys, monkeypatch, target, message):
    monkeypatch.chdir(tmp_path)
    f = _static_csv(tmp_path)
    assert main(["identify", "static-map", f, "--velocity", "vel", "--force", "F", "--json", target]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert sorted(os.listdir(tmp_path)) == ["map.csv"]
