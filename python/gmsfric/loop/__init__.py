"""Residual-driven identification loop: measured data -> baseline -> residual analysis
-> effect catalogue -> justified, better model, with before/after errors.

Typical use::

    from gmsfric.loop import load_axis_data, run_loop
    est = load_axis_data("run1.mat", time="t", position="qm", command="vir", gain="gtau")
    val = load_axis_data("run2.mat", time="t", position="qm", command="vir", gain="gtau")
    result = run_loop(est, val)
    print(result.table())
    result.save("loop-report")   # figures (PNG) and loop.json

See ``docs/loop.md`` for the method and the EMPS results.
"""

from __future__ import annotations

from .closedloop import closed_loop_report, simulate_model
from .data import AxisData, load_axis_data
from .effects import CATALOGUE, Effect
from .idim import LinearModel, Preprocessing, Signals, fit_baseline, reference_model, relative_error
from .residuals import Finding, analyse
from .results import LoopResult, Step
from .select import LoopConfig, run_loop

__all__ = [
    "AxisData",
    "load_axis_data",
    "Preprocessing",
    "Signals",
    "LinearModel",
    "fit_baseline",
    "reference_model",
    "relative_error",
    "Effect",
    "CATALOGUE",
    "Finding",
    "analyse",
    "LoopConfig",
    "LoopResult",
    "Step",
    "run_loop",
    "simulate_model",
    "closed_loop_report",
]
