"""`gmsfric demo` runs on the shipped example data and produces the figures it names."""

from __future__ import annotations

import pytest

from gmsfric import demo
from gmsfric.cli import main


def test_demo_summary_and_figures(tmp_path, capsys):
    summary = demo.run(tmp_path / "figs")
    for name in ("friction_map.png", "gms_hysteresis.png", "closed_loop_glitches.png"):
        assert (tmp_path / "figs" / name).stat().st_size > 5000
    sm = summary["static_map"]
    # the EMPS benchmark's published mass and Coulomb level (95.11 kg, 20.39 N), from an excerpt
    assert sm["M"] == pytest.approx(95.11, rel=0.05)
    assert sm["Fc"] == pytest.approx(20.39, rel=0.15)
    assert sm["error_pct"] < 6.0
    # the example pre-sliding data were made with the paper's GMS plus 0.2 mN noise
    assert summary["presliding"]["rms_force_error_N"] < 5e-4
    cl = summary["closed_loop"]
    # the paper's claim: GMS glitches exceed the (Simulink-style) static map's, which exceed none
    assert cl["none"]["peak_error_m"] == 0.0
    assert cl["gms"]["peak_error_m"] > cl["static"]["peak_error_m"] > 0
    assert str(tmp_path / "figs") in capsys.readouterr().out


def test_cli_demo_without_plots(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "x"), "--no-plots"]) == 0
    assert "Static friction map" in capsys.readouterr().out
    assert not (tmp_path / "x" / "friction_map.png").exists()


def test_cli_without_command_prints_help(capsys):
    assert main([]) == 2
    assert "demo" in capsys.readouterr().out
