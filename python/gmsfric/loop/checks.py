"""Checks of a loop result that a user should see before trusting its numbers.

The loop can end with "no effect added" and a tidy table on a run that did not let it identify
anything: a force column unrelated to the motion, a run in one direction only (Coulomb friction
and an offset are then one number), a clipped drive, a time or position column in another unit
than declared.  These checks put such findings in the result's ``diagnostics`` (``{"code",
"parameter", "message"}`` in the JSON) and warn each with :class:`~gmsfric.errors.FitWarning`;
the CLI prints them under the table.  They only report: the selection does not use them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..identify.diagnostics import Findings, check_saturation

if TYPE_CHECKING:
    from .results import LoopResult

#: Relative rms error (%) of the final model on the moving rows of the estimation run above which
#: it explains too little of the force for its parameters to describe the axis.  On all rows the
#: error of a good fit can exceed it: a stuck axis holds any force up to break-away.
POOR_FIT_PCT = 50.0

#: Correlation of two baseline parameters beyond which the run does not tell them apart.
CONFOUNDED = 0.999

#: The baseline's parameters, the ones a user reads as the axis's physics.
BASELINE_PARAMETERS = ("M", "Fv", "Fc", "offset")

#: Sample rates (Hz) of servo logs: a rate outside is most likely a time column in another unit
#: than declared (a 1 kHz log in ms read as s is sampled at 1 Hz).
SAMPLE_RATE_RANGE = (20.0, 200e3)

#: Top speeds (99th percentile; m/s linear, rad/s rotary) beyond those of servo axes (linear
#: motors reach a few m/s, motor shafts a few thousand rad/s): most likely a position in mm or
#: deg read as m or rad.
TOP_SPEED = {"linear": 20.0, "rotary": 2000.0}


def check_result(result: "LoopResult") -> Findings:
    """Findings about ``result`` (see the module docstring); empty on a run that identifies."""
    found = Findings()
    data = result.split.est.data
    if data.command is not None:
        check_saturation(found, "command", data.command)
    else:
        check_saturation(found, "force", data.force)
    rate = 1.0 / data.dt
    if not SAMPLE_RATE_RANGE[0] <= rate <= SAMPLE_RATE_RANGE[1]:
        found.add("units", f"the run is sampled at {rate:.4g} Hz, outside the {SAMPLE_RATE_RANGE[0]:g} Hz to {SAMPLE_RATE_RANGE[1]:.0f} Hz "
                           "of servo logs: is the time column in the declared unit (--time-unit)?", "time")
    kind = "rotary" if result.rotary else "linear"
    speed = result.split.est.v_scale
    if speed > TOP_SPEED[kind]:
        unit = "rad/s" if result.rotary else "m/s"
        found.add("units", f"the axis moves at up to {speed:.4g} {unit}, beyond the {TOP_SPEED[kind]:g} {unit} of servo axes: "
                           "is the position column in the declared unit (--position-unit)?", "position")
    error = result.split.errors_moving(result.final)[0]
    if error > POOR_FIT_PCT:
        found.add("poor_fit", f"the final model leaves {error:.0f} % of the force unexplained (relative rms error on the moving rows of the estimation run): "
                              "its parameters describe little of this run; check the force column, --gain and the units", None)
    final = result.final
    params = final.params()
    mass = params.get("M", {}).get("value")
    if mass is not None and mass <= 0:
        inertia = "kg m^2" if result.rotary else "kg"
        found.add("degenerate", f"the fitted inertia M = {mass:.4g} {inertia} is not positive: the run does not determine it "
                                "(too little acceleration against the friction?), and the model cannot be simulated", "M")
    if final.cov is not None:
        names = final.param_names
        std = np.sqrt(np.clip(np.diag(final.cov), 0.0, None))
        idx = [i for i, n in enumerate(names) if n in BASELINE_PARAMETERS and std[i] > 0]
        for a_pos, i in enumerate(idx):
            for j in idx[a_pos + 1:]:
                corr = float(final.cov[i, j] / (std[i] * std[j]))
                if abs(corr) > CONFOUNDED:
                    hint = ""
                    if {names[i], names[j]} == {"Fc", "offset"}:
                        hint = " (a run in one direction only: sign(qd) is then a constant)"
                    found.add("degenerate", f"{names[i]} and {names[j]} are not told apart by this run (correlation {corr:+.4f}){hint}: "
                                            "only a combination of them is determined",
                              f"{names[i]},{names[j]}")
    return found
