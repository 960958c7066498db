"""Quadrant glitches and friction compensation (paper Section 4 and its future work).

* :func:`run_sinusoid` - the paper's Fig. 14: 10 mm, 0.01 Hz sinusoid, no friction / static map / GMS.
* :func:`run_circle` - XY circle (ballbar) test, radial error and glitch per quadrant.
* :func:`run_compensation`, :func:`friction_feedforward`, :func:`compensation_sweep` - model-based
  friction feedforward from the static map and from GMS.
* :func:`glitch_metrics`, :func:`find_reversals` - peak, duration and area at each reversal.

Definitions and the measured numbers: ``docs/glitch.md``.
"""

from __future__ import annotations

from .circle import QUADRANTS, CircleResult, run_circle
from .compensation import STRATEGIES, CompensationResult, compensation_sweep, friction_feedforward, run_compensation
from .metrics import GlitchEvent, GlitchReport, find_reversals, glitch_metrics
from .plots import plot_circle_polar, plot_compensation, plot_tracking_errors
from .scenario import DEFAULT_GAINS, PAPER_TABLE3, ScenarioResult, run_sinusoid, scenario_controller, sinusoid_reference, table3_plant

__all__ = [
    "run_sinusoid",
    "ScenarioResult",
    "scenario_controller",
    "sinusoid_reference",
    "table3_plant",
    "DEFAULT_GAINS",
    "PAPER_TABLE3",
    "run_circle",
    "CircleResult",
    "QUADRANTS",
    "run_compensation",
    "CompensationResult",
    "friction_feedforward",
    "compensation_sweep",
    "STRATEGIES",
    "glitch_metrics",
    "find_reversals",
    "GlitchEvent",
    "GlitchReport",
    "plot_tracking_errors",
    "plot_circle_polar",
    "plot_compensation",
]
