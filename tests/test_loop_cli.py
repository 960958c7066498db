"""`gmsfric loop` on a CSV file: the JSON contract, figures, and errors naming the problem."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gmsfric.loop.cli import main as loop_main
from gmsfric.loop.cli import register
from gmsfric.loop.rigs import Rig, simulate_rig


def _parse(argv):
    import argparse

    p = argparse.ArgumentParser(prog="gmsfric")
    sub = p.add_subparsers(dest="command")
    register(sub)
    return p.parse_args(["loop", *argv])


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
    args = _parse([str(path), "--time", "t_ms", "--time-unit", "ms", "--position", "x_mm", "--position-unit", "mm",
                   "--command", "u", "--gain", str(gain), "--json", str(out), "--plot", str(figs), "--quiet"])
    assert loop_main(args) == 0
    d = json.loads(out.read_text())
    for key in ("model", "estimation_error_pct", "validation_error_pct"):
        assert key in d["baseline"]
    assert d["final"]["effects"] == ["position_dependent_force"]
    assert d["final"]["validation_error_pct"] < d["baseline"]["validation_error_pct"]
    acc = [s for s in d["steps"] if s["accepted"]]
    assert acc[0]["evidence"]["residual_test"]["variable"] == "position"
    assert "held-out" in d["validation"]
    assert (figs / "steps.png").exists() and (figs / "residual_baseline_estimation_position.png").exists()
    assert "before -> after" in capsys.readouterr().out


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--time", "t_ms", "--position", "nope", "--force", "u"], "unknown position column 'nope'"),
        (["--time", "t_ms", "--position", "x_mm", "--command", "u"], "needs --gain"),
        (["--time", "t_ms", "--position", "x_mm", "--command", "u", "--gain", "kgain"], "'kgain' is neither a number nor a scalar"),
    ],
)
def test_cli_errors_name_the_problem(rig_csv, argv, message, capsys):
    from gmsfric.cli import main

    path, _ = rig_csv
    assert main(["loop", str(path), *argv, "--quiet"]) == 2
    assert message in capsys.readouterr().err
