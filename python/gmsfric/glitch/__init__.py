"""Quadrant glitches and friction compensation (paper Section 4 and its future work).

* :func:`run_sinusoid` - the paper's Fig. 14: 10 mm, 0.01 Hz sinusoid, no friction / static map
  (Simulink reading: linear region below 1e-4 m/s) / GMS, plus the static map with true stiction.
* :func:`run_circle` - XY circle (ballbar) test, radial error and glitch per quadrant.
* :func:`run_compensation`, :func:`friction_feedforward`, :func:`compensation_sweep` - model-based
  friction feedforward from the static map and from GMS, and a PID + disturbance observer.
* :func:`glitch_metrics`, :func:`find_reversals` - peak, duration and area at each reversal.

Definitions and the measured numbers: ``docs/glitch.md``.
"""

from __future__ import annotations

from .circle import QUADRANTS, CircleResult, run_circle
from .compensation import DOB_CUTOFF_HZ, EXTRA_STRATEGIES, STRATEGIES, CompensationResult, compensation_sweep, friction_feedforward, run_compensation
from .metrics import GlitchEvent, GlitchReport, find_reversals, glitch_metrics
from .plots import plot_circle_polar, plot_compensation, plot_tracking_errors
from .results import GlitchStudy
from .scenario import (
    DEFAULT_GAINS,
    PAPER_STATIC_V_LINEAR,
    PAPER_TABLE3,
    STICTION,
    ScenarioResult,
    paper_static_map,
    run_sinusoid,
    scenario_controller,
    sinusoid_reference,
    table3_plant,
)

__all__ = [
    "run_sinusoid",
    "ScenarioResult",
    "GlitchStudy",
    "scenario_controller",
    "sinusoid_reference",
    "table3_plant",
    "DEFAULT_GAINS",
    "PAPER_TABLE3",
    "PAPER_STATIC_V_LINEAR",
    "STICTION",
    "paper_static_map",
    "run_circle",
    "CircleResult",
    "QUADRANTS",
    "run_compensation",
    "CompensationResult",
    "friction_feedforward",
    "compensation_sweep",
    "STRATEGIES",
    "EXTRA_STRATEGIES",
    "DOB_CUTOFF_HZ",
    "glitch_metrics",
    "find_reversals",
    "GlitchEvent",
    "GlitchReport",
    "plot_tracking_errors",
    "plot_circle_polar",
    "plot_compensation",
]
