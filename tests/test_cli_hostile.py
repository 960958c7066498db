"""Hostile but fair command lines: every one ends with exit code 2 (1 for a failed fit, 130 on
Ctrl-C) and exactly one line on stderr, before any work; the user's files are never replaced."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from scipy.io import savemat

from gmsfric import presets
from gmsfric.cli import main
from gmsfric.model_io import save_model


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("hostile")
    t = np.arange(400) * 1e-3
    x = 1e-5 * np.sin(2 * np.pi * 2 * t)
    text = "t,x,F,u\n" + "\n".join(f"{a:.6g},{b:.6g},{np.tanh(b * 1e5):.6g},{np.cos(a):.6g}" for a, b in zip(t, x)) + "\n"
    (d / "data.csv").write_text(text)
    (d / "utf16.csv").write_bytes(text.encode("utf-16"))  # with a byte-order mark
    (d / "utf16le.csv").write_bytes(text.encode("utf-16-le"))  # without
    (d / "latin1.csv").write_bytes("t,x,F\n1,2,3\n".encode() + "4,5,\xb5\n".encode("latin-1"))
    (d / "binary.csv").write_bytes(bytes(range(256)) * 8)
    (d / "empty.csv").write_text("")
    (d / "folder").mkdir()
    (d / "existing.txt").write_text("not a folder")
    savemat(d / "run.mat", {"t": t[:, None], "x": x[:, None], "F": np.tanh(x * 1e5)[:, None]})
    savemat(d / "huge.mat", {"t": t[:, None], "x": x[:, None] * 1e300, "F": np.tanh(x * 1e5)[:, None]})
    (d / "bad.json").write_text("{not json")
    (d / "list.json").write_text("[1, 2, 3]")
    (d / "furlong.json").write_text(json.dumps({"model": "static_map", "parameters": {n: 1.0 for n in ("fc", "fs", "vs", "sigma", "delta")},
                                                "units": {"fc": "N", "fs": "N", "vs": "furlong/s", "sigma": "N s/m", "delta": "1"}}))
    (d / "nogain.json").write_text(json.dumps({"model": "plant", "parameters": {"a": 0.02, "b": 168.4, "c": 176.8, "delay": 1.29e-3},
                                               "units": {"a": "m/(V s^2)", "b": "1/s", "c": "1/s^2", "delay": "s"}}))
    save_model(presets.paper_plant(), d / "plant.json")
    p = presets.paper_plant()
    save_model(p.__class__(p.a, p.b, p.c, 1e6, p.force_gain), d / "slow_plant.json")
    (d / "link.csv").symlink_to(d / "data.csv")
    return d


PRESLIDING = ["identify", "presliding", "{d}/data.csv", "--time", "t", "--position", "x", "--force", "F"]
STATIC = ["identify", "static-map", "{d}/data.csv", "--velocity", "x", "--force", "F"]
PLANT = ["identify", "plant", "{d}/data.csv", "--time", "t", "--input", "u", "--output", "x"]
LOOP = ["loop", "{d}/run.mat", "--time", "t", "--position", "x", "--force", "F"]

CASES = [
    # inputs
    (["identify", "presliding", "{d}/folder", "--time", "t", "--position", "x", "--force", "F"], 2, "is a directory"),
    (["identify", "presliding", "{d}/binary.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "binary file"),
    (["identify", "presliding", "{d}/utf16.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "UTF-16"),
    (["identify", "presliding", "{d}/utf16le.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "UTF-16"),
    (["identify", "presliding", "{d}/latin1.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "not UTF-8"),
    (["identify", "presliding", "{d}/missing.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "no such file"),
    (["identify", "presliding", "{d}/empty.csv", "--time", "t", "--position", "x", "--force", "F"], 2, "file is empty"),
    (["loop", "{d}/huge.mat", "--time", "t", "--position", "x", "--force", "F"], 2, "(position) reaches 1e+295, beyond 1.3e+147 where the fits overflow"),
    (["loop", "{d}/folder", "--time", "t", "--position", "x", "--force", "F"], 2, "is a directory"),
    ([*LOOP, "--validate", "{d}/folder"], 2, "is a directory"),
    (["glitch", "--plant", "{d}/folder"], 2, "is a directory"),
    (["glitch", "--friction", "{d}/binary.csv"], 2, "binary file"),
    # numbers
    ([*PRESLIDING, "--max-blocks", "0"], 2, "--max-blocks: must be a positive integer, got 0"),
    ([*PRESLIDING, "--blocks", "0"], 2, "--blocks: must be a positive integer"),
    ([*PRESLIDING, "--blocks", "two"], 2, "'two' is not an integer"),
    ([*STATIC, "--bootstrap", "-1"], 2, "--bootstrap: must be an integer >= 0"),
    ([*PLANT, "--nperseg", "0"], 2, "--nperseg: must be an integer >= 16"),
    ([*PLANT, "--fmin", "nan"], 2, "--fmin: must be a finite number"),
    ([*PLANT, "--fmax", "-1"], 2, "--fmax: must be > 0"),
    ([*PLANT, "--fmin", "10", "--fmax", "5"], 2, "must be below --fmax"),
    ([*PLANT, "--force-gain", "0"], 2, "--force-gain: must be > 0"),
    ([*LOOP, "--holdout", "nan"], 2, "--holdout: must be a finite number"),
    ([*LOOP, "--holdout", "1.5"], 2, "--holdout: must be between 0 and 1"),
    ([*LOOP, "--drive-limit", "-1"], 2, "--drive-limit: must be > 0"),
    ([*LOOP, "--kp", "160"], 2, "--reference, --kp and --kv together"),
    (["glitch", "--dt", "1e-12"], 2, "would need"),
    (["glitch", "--dt", "0"], 2, "--dt: must be > 0"),
    (["glitch", "--frequency", "nan"], 2, "--frequency: must be a finite number"),
    (["glitch", "--amplitude", "-1"], 2, "--amplitude: must be > 0"),
    (["glitch", "--frequency", "1e-9"], 2, "would need"),
    (["paper", "--seed", "-1"], 2, "--seed: must be an integer >= 0"),
    # units
    ([*PRESLIDING, "--position-unit", "furlong"], 2, "unknown unit 'furlong'"),
    ([*PRESLIDING, "--force-unit", "mm"], 2, "not a force unit"),
    ([*PRESLIDING, "--position-unit", "rad"], 2, "rotary"),
    ([*STATIC, "--velocity-unit", "mm"], 2, "not a velocity unit"),
    ([*PLANT, "--force-gain", "35", "--force-gain-unit", "N/A"], 2, "different drive input"),
    ([*LOOP, "--time-unit", "furlong"], 2, "unknown unit 'furlong'"),
    # model files
    (["glitch", "--plant", "{d}/bad.json"], 2, "not JSON"),
    (["glitch", "--plant", "{d}/list.json"], 2, "expected a JSON object"),
    (["glitch", "--plant", "{d}/nogain.json"], 2, "no force gain"),
    (["glitch", "--friction", "{d}/furlong.json"], 2, "unknown unit 'furlong'"),
    (["glitch", "--friction", "{d}/plant.json"], 2, "holds a Plant"),
    (["glitch", "--plant", "{d}/slow_plant.json"], 2, "would need"),
    # outputs
    ([*PRESLIDING, "--json", "{d}/data.csv"], 2, "is the input file"),
    ([*PRESLIDING, "--json", "{d}/link.csv"], 2, "is the input file"),
    ([*LOOP, "--json", "{d}/run.mat"], 2, "is the input file"),
    (["glitch", "--friction", "{d}/furlong.json", "--json", "{d}/furlong.json"], 2, "is the input file"),
    ([*PRESLIDING, "--json", "{d}/nowhere/out.json"], 2, "does not exist"),
    ([*PRESLIDING, "--json", "{d}/folder"], 2, "is a directory"),
    ([*PRESLIDING, "--plot", "{d}/existing.txt"], 2, "not a directory"),
    ([*PRESLIDING, "--plot", "{d}/nowhere/figs"], 2, "does not exist"),
    (["paper", "--json", "{d}/nowhere/p.json"], 2, "does not exist"),
    (["demo", "--out", "{d}/existing.txt"], 2, "not a directory"),
    # the command line itself
    ([*PRESLIDING, "--no-such-option"], 2, "unrecognized arguments"),
    (["frobnicate"], 2, "invalid choice"),
    (["identify"], 2, "required"),
    ([*PRESLIDING, "-q", "-v"], 2, "exclude each other"),
]


def _argv(template, d):
    return [a.format(d=d) for a in template]


@pytest.mark.parametrize("template, code, message", CASES, ids=[" ".join(c[0][:2] + c[0][-2:]) for c in CASES])
def test_hostile_command_lines_give_one_line_and_exit_2(files, template, code, message, capsys, monkeypatch):
    from gmsfric.identify import frf, presliding, static_map
    from gmsfric.loop import cli as loop_cli

    def no_work(*a, **k):
        raise AssertionError("the work started before the command line was checked")

    for mod, name in ((presliding, "fit_presliding"), (static_map, "fit_static_map"), (frf, "estimate_frf"), (loop_cli, "run_loop")):
        monkeypatch.setattr(mod, name, no_work)
    before = {p: p.read_bytes() for p in files.iterdir() if p.is_file()}
    rc = main(_argv(template, files))
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert rc == code, err
    assert len(lines) == 1 and lines[0].startswith("gmsfric") and ": error: " in lines[0], err
    assert message in lines[0]
    assert "Traceback" not in err
    assert {p: p.read_bytes() for p in files.iterdir() if p.is_file()} == before  # no file replaced or changed


def test_json_onto_the_input_leaves_it_byte_identical_in_a_real_process(files):
    data = files / "data.csv"
    before = data.read_bytes()
    proc = subprocess.run([sys.executable, "-m", "gmsfric.cli", *_argv(PRESLIDING, files), "--json", str(data)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [f"gmsfric identify presliding: error: --json {data} is the input file {data}: refusing to overwrite it"]
    assert data.read_bytes() == before
    proc = subprocess.run([sys.executable, "-m", "gmsfric.loop", str(files / "run.mat"), "--time", "t", "--position", "x", "--force", "F",
                           "--holdout", "nan"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and len(proc.stderr.strip().splitlines()) == 1 and "--holdout" in proc.stderr


def test_a_failed_fit_exits_1(files, capsys):
    rc = main(_argv(STATIC, files)[:2] + [str(files / "data.csv"), "--time", "t", "--position", "x", "--force", "F", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "plateaus" in err[0]


@pytest.mark.parametrize(
    "exc, code, message",
    [
        (KeyboardInterrupt(), 130, "gmsfric identify presliding: interrupted"),
        (RuntimeError("boom\nsecond line"), 2, "internal error, RuntimeError: boom second line"),
        (MemoryError("cannot allocate 8 TiB"), 2, "out of memory: cannot allocate 8 TiB"),
        (PermissionError(13, "Permission denied", "/root/x.json"), 2, "/root/x.json: Permission denied"),
        (ValueError("math domain"), 2, "internal error, ValueError"),
    ],
)
def test_any_exception_is_one_line_and_debug_shows_the_traceback(files, monkeypatch, capsys, exc, code, message):
    from gmsfric.identify import presliding

    def raise_it(*a, **k):
        raise exc

    monkeypatch.setattr(presliding, "fit_presliding", raise_it)
    assert main(_argv(PRESLIDING, files)) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0]
    assert main([*_argv(PRESLIDING, files), "--debug"]) == code
    err = capsys.readouterr().err
    if code != 130:
        assert "Traceback" in err and message in err.strip().splitlines()[-1]


def test_quiet_and_verbose_map_to_logging(files, tmp_path, capsys):
    out = tmp_path / "p.json"
    assert main(["glitch", "--plant", str(files / "plant.json"), "--dt", "2e-3", "--frequency", "0.05", "--json", str(out)]) == 0
    err = capsys.readouterr().err
    assert f"wrote {out}" in err and "sinusoid peak glitch" in err and "\r" not in err  # progress is silent off a terminal
    assert main(["glitch", "--plant", str(files / "plant.json"), "--dt", "2e-3", "--frequency", "0.05", "--json", str(out), "-q"]) == 0
    assert capsys.readouterr().err == ""
    doc = json.loads(out.read_text())
    assert doc["kind"] == "glitch" and doc["parameters"]["plant"]["force_gain"] == presets.paper_plant().force_gain
    assert doc["provenance"]["input_files"][0]["path"] == str(files / "plant.json")


def test_the_api_refuses_the_same_numbers():
    from gmsfric import InvalidInputError
    from gmsfric.identify import fit_presliding
    from gmsfric.loop import LoopConfig

    with pytest.raises(InvalidInputError, match="`holdout_fraction`"):
        LoopConfig(holdout_fraction=float("nan"))
    with pytest.raises(InvalidInputError, match="`inner_folds`"):
        LoopConfig(inner_folds=1)
    t = np.arange(100) * 1e-3
    with pytest.raises(InvalidInputError, match="`max_blocks` must be a positive integer"):
        fit_presliding(t, np.sin(t), np.sin(t), max_blocks=0)
