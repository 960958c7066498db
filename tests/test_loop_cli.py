"""`gmsfric loop` on a CSV file: the JSON contract, figures, and errors naming the problem."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gmsfric.cli import main
from gmsfric.loop.rigs import Rig, simulate_rig


@pytest.fixture(scope="module")
def rig_csv(tmp_path_factory):
    d = simulate_rig(Rig(effect="position_dependent_force", seed=51, fs=1000.0, duration=14.0))
    path = tmp_path_factory.mktemp("rig") / "rig.csv"
    assert d.command is not None
    cols = np.column_stack([d.t * 1e3, d.position * 1e3, d.command, d.reference * 1e3])
    np.savetxt(path, cols, delimiter=",", header="t_ms,x_mm,u,ref_mm", comments="")
    return path, d.gain


def test_cli_json_contract_and_figures(rig_csv, tmp_path, capsys):
    path, gain = rig_csv
    out, figs = tmp_path / "r.json", tmp_path / "figs"
    assert main(["loop", str(path), "--time", "t_ms", "--time-unit", "ms", "--position", "x_mm", "--position-unit", "mm",
                 "--command", "u", "--gain", str(gain), "--json", str(out), "--plot", str(figs), "--quiet"]) == 0
    d = json.loads(out.read_text())
    for key in ("model", "estimation_error_pct", "validation_error_pct"):
        assert key in d["baseline"]
    assert d["final"]["effects"] == ["position_dependent_force"]
    assert d["final"]["validation_error_pct"] < d["baseline"]["validation_error_pct"]
    acc = [s for s in d["steps"] if s["accepted"]]
    assert acc[0]["evidence"]["residual_test"]["variable"] == "position"
    assert "held-out" in d["validation"]
    assert (figs / "steps.png").exists() and (figs / "residual_baseline_estimation_position.png").exists()
    fv = d["final"]["parameters"]["Fv"]
    assert fv["stderr"] == fv["std"] > 0 and fv["unit"] == "N s/m" and d["final"]["parameters"]["M"]["unit"] == "kg"
    assert d["kind"] == "loop" and d["provenance"]["columns"]["position"] == "x_mm" and d["provenance"]["units"]["time"] == "ms"
    assert d["provenance"]["input_files"][0]["path"] == str(path) and len(d["provenance"]["input_files"][0]["sha256"]) == 64
    assert "before -> after" in capsys.readouterr().out
    assert d["preprocessing"] == {"cutoff_hz": 100.0, "chosen_by": "the recipe, min(100 Hz, fs / 10)"}  # a 1 kHz log


def test_cli_cutoff_is_given_to_the_filter(rig_csv, tmp_path, capsys):
    path, gain = rig_csv
    out = tmp_path / "r.json"
    base = ["loop", str(path), "--time", "t_ms", "--time-unit", "ms", "--position", "x_mm", "--position-unit", "mm",
            "--command", "u", "--gain", str(gain), "--quiet"]
    assert main([*base, "--cutoff-hz", "40", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["preprocessing"] == {"cutoff_hz": 40.0, "chosen_by": "given"}
    assert main([*base, "--cutoff-hz", "1e9", "--json", str(out)]) == 0
    assert json.loads(out.read_text())["preprocessing"] == {"cutoff_hz": 450.0, "chosen_by": "given (1e+09 Hz, limited to 0.45 x fs)"}
    capsys.readouterr()
    assert main([*base, "--cutoff-hz", "-5"]) == 2
    err = capsys.readouterr().err
    assert "--cutoff-hz" in err and "must be > 0" in err and "Traceback" not in err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--time", "t_ms", "--position", "nope", "--force", "u"], "unknown position column 'nope'"),
        (["--time", "t_ms", "--position", "x_mm", "--command", "u"], "needs --gain"),
        (["--time", "t_ms", "--position", "x_mm", "--command", "u", "--gain", "kgain"], "'kgain' is neither a number nor a scalar"),
    ],
)
def test_cli_errors_name_the_problem(rig_csv, argv, message, capsys):
    path, _ = rig_csv
    assert main(["loop", str(path), *argv, "--quiet"]) == 2
    assert message in capsys.readouterr().err


def _loop_argv(path, gain, *extra):
    return ["loop", str(path), "--time", "t_ms", "--time-unit", "ms", "--position", "x_mm", "--position-unit", "mm",
            "--command", "u", "--gain", str(gain), *extra]


def test_cli_refuses_the_estimation_run_as_validation_run(rig_csv, tmp_path, capsys):
    path, gain = rig_csv
    copy = tmp_path / "copy.csv"
    copy.write_bytes(path.read_bytes())
    for val, why in ((path, "the same file"), (copy, "identical content")):
        assert main(_loop_argv(path, gain, "--validate", str(val))) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"--validate {val} is the estimation run" in err[0] and why in err[0]


@pytest.mark.parametrize("extra, message", [
    (["--validate", "{other}", "--holdout", "0.2"], "--holdout goes without --validate"),
    (["--disturbance", "u"], "--disturbance names a column of the validation run: it needs --validate"),
    (["--reference", "ref_mm"], "--reference is only used by the closed-loop simulation"),
    (["--drive-limit", "10"], "--drive-limit is only used by the closed-loop simulation"),
    (["--position-unit", ""], "--position-unit"),
])
def test_cli_refuses_flags_it_would_ignore(rig_csv, tmp_path, capsys, extra, message):
    path, gain = rig_csv
    other = tmp_path / "other.csv"
    other.write_text(path.read_text().replace("\n", "\n", 1) + "\n")  # same data, other bytes
    assert main([*_loop_argv(path, gain), *[e.format(other=other) for e in extra]]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_cli_reads_a_matlab_log_of_several_axes_as_the_same_run(rig_csv, tmp_path, capsys):
    # a MATLAB user's log: a struct, one matrix column per axis, the other axes held
    path, gain = rig_csv
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    held = np.full_like(raw[:, 1], 12.5)
    from scipy.io import savemat
    savemat(tmp_path / "log.mat", {"log": {"t": raw[:, 0], "x": np.column_stack([held, raw[:, 1], held]),
                                           "u": np.column_stack([0 * held, raw[:, 2], 0 * held]), "kt": gain}})
    outs = []
    for src, cols in ((path, ["t_ms", "x_mm", "u", str(gain)]), (tmp_path / "log.mat", ["log.t", "log.x(:,2)", "log.u(:,2)", "log.kt"])):
        out = tmp_path / f"{src.stem}.json"
        assert main(["loop", str(src), "--time", cols[0], "--time-unit", "ms", "--position", cols[1], "--position-unit", "mm",
                     "--command", cols[2], "--gain", cols[3], "--json", str(out), "--quiet"]) == 0
        outs.append(json.loads(out.read_text()))
    assert outs[1]["final"]["effects"] == outs[0]["final"]["effects"] == ["position_dependent_force"]
    assert outs[1]["final"]["validation_error_pct"] == pytest.approx(outs[0]["final"]["validation_error_pct"], rel=1e-9)
    assert outs[1]["provenance"]["columns"]["position"] == "log.x(:,2)"
    capsys.readouterr()
    assert main(["loop", str(tmp_path / "log.mat"), "--time", "log.t", "--position", "log.x", "--command", "log.u(:,2)", "--gain", "log.kt", "--quiet"]) == 2
    assert f"'log.x' is a {raw.shape[0]}x3 matrix" in capsys.readouterr().err


def test_cli_refuses_a_unit_the_files_units_row_contradicts(rig_csv, tmp_path, capsys):
    path, gain = rig_csv
    lines = path.read_text().splitlines()
    labelled = tmp_path / "labelled.csv"
    labelled.write_text("\n".join([lines[0], "ms,mm,V,mm", *lines[1:]]) + "\n")
    argv = ["loop", str(labelled), "--time", "t_ms", "--time-unit", "ms", "--position", "x_mm", "--command", "u", "--gain", str(gain), "--quiet"]
    assert main(argv) == 2  # --position-unit left at its default, m
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "column 'x_mm' is in mm by the file, but --position-unit is 'm'" in err[0]


def test_cli_takes_a_sample_rate_for_a_log_without_time(rig_csv, tmp_path, capsys):
    path, gain = rig_csv
    raw = np.loadtxt(path, delimiter=",", skiprows=1)
    rate = 1e3 / np.median(np.diff(raw[:, 0]))  # the rig logs at 1 kHz, stamped in ms
    untimed = tmp_path / "untimed.csv"
    np.savetxt(untimed, raw[:, 1:3], delimiter=",", header="x_mm,u", comments="")
    outs = []
    for src, timing in ((path, ["--time", "t_ms", "--time-unit", "ms"]), (untimed, ["--sample-rate", f"{rate:.12g}"])):
        out = tmp_path / f"{src.stem}.json"
        assert main(["loop", str(src), *timing, "--position", "x_mm", "--position-unit", "mm", "--command", "u", "--gain", str(gain),
                     "--json", str(out), "--quiet"]) == 0
        outs.append(json.loads(out.read_text()))
    assert outs[1]["final"]["effects"] == outs[0]["final"]["effects"]
    assert outs[1]["final"]["validation_error_pct"] == pytest.approx(outs[0]["final"]["validation_error_pct"], rel=1e-6)
    assert outs[1]["provenance"]["sample_rate_hz"] == pytest.approx(rate)
    capsys.readouterr()
    base = ["loop", str(untimed), "--position", "x_mm", "--command", "u", "--gain", str(gain), "--quiet"]
    assert main([*base, "--sample-rate", "1000", "--time-unit", "ms"]) == 2
    assert "--time-unit goes with --time" in capsys.readouterr().err
    assert main([*base, "--sample-rate", "0"]) == 2
    assert "--sample-rate" in capsys.readouterr().err
