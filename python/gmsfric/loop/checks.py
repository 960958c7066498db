"""Checks of a loop result that a user should see before trusting its numbers.

The loop can end with "no effect added" and a tidy table on a run that did not let it identify
anything: a force column unrelated to the motion, a run in one direction only (Coulomb friction
and an offset are then one number), a clipped drive, a time or position column in another unit
than declared, a held-out run that leaves the estimation run's travel, an effect the data
support that was held back only to keep the baseline's physics plausible; and gaps in a log,
which the loop leaves out, and an angle that wrapped around, which it unwraps.  These checks put such
findings in the result's ``diagnostics`` (``{"code", "parameter", "message"}`` in the JSON) and
warn each with :class:`~gmsfric.errors.FitWarning`; the CLI prints them under the table.  They
only report: the selection does not use them.

:func:`check_closed_loop` judges the closed-loop replay (``--reference --kp --kv``): a replay
whose force error is far beyond the inverse model's is a controller, gain or unit that does not
match the measured loop (``poor_fit``, parameter ``closed_loop``), and a replayed drive that sits
at its limit is a saturation the inverse model never saw (``saturation``, parameter
``closed_loop``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..identify.diagnostics import Findings, check_saturation, fraction_at_limit
from .data import GAP_STEPS
from .idim import GAP_SETTLING_PERIODS

if TYPE_CHECKING:
    from ..system import PID, Cascade
    from .idim import Signals
    from .results import LoopResult, Step

#: Relative rms error (%) of the final model on the moving rows of the estimation run above which
#: it explains too little of the force for its parameters to describe the axis.  On all rows the
#: error of a good fit can exceed it: a stuck axis holds any force up to break-away.
POOR_FIT_PCT = 50.0

#: Closed-loop force error (%) of a replay above which the simulated loop does not behave like
#: the measured one, whatever the inverse model's error.  A model whose inverse error is a few %
#: replays within a few % on a loop that matches (EMPS: 3 %); many times more is a controller
#: gain in other units than the drive's, a wrong --gain, or a model the loop cannot hold.
CLOSED_LOOP_POOR_PCT = 50.0

#: Below :data:`CLOSED_LOOP_POOR_PCT`, a replay error above this many times the model's inverse
#: error (on the moving rows of the estimation run) and above :data:`CLOSED_LOOP_FLOOR_PCT` is
#: reported too: a 40 % replay of a 1 % model is as far off as a 130 % replay of a 3 % one.
CLOSED_LOOP_RATIO = 10.0

#: Replay errors (%) never reported by the ratio alone (quantisation and filtering leave a few %).
CLOSED_LOOP_FLOOR_PCT = 20.0

#: Share of a replay's samples at the drive limit beyond which the replay counts as saturated.
CLOSED_LOOP_SATURATED = 0.01

#: Correlation of two baseline parameters beyond which the run does not tell them apart.
CONFOUNDED = 0.999

#: The baseline's parameters, the ones a user reads as the axis's physics.
BASELINE_PARAMETERS = ("M", "Fv", "Fc", "offset")

#: Sample rates (Hz) of servo logs: a rate outside is most likely a time column in another unit
#: than declared (a 1 kHz log in ms read as s is sampled at 1 Hz).
SAMPLE_RATE_RANGE = (20.0, 200e3)

#: Share of the held-out run's moving rows outside the estimation run's travel above which the
#: held-out figures are reported as extrapolation: position-dependent terms are fitted on the
#: estimation travel only (their polynomials are held at its ends beyond it).
OUTSIDE_TRAVEL = 0.10

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
    _check_gaps(found, result)
    _check_wraps(found, result)
    _check_travel(found, result)
    _check_held_back(found, result)
    _check_unconfirmed(found, result)
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


def _strongest_refused(result: "LoopResult", flag: str) -> dict[str, "Step"]:
    """Per effect left out of the final model, its refused entering step (exchanges left out)
    whose evidence carries ``flag``, the one with the largest held-out t."""
    best: dict[str, Step] = {}
    for step in result.steps:
        ev = step.evidence
        if step.accepted or step.effect in result.effects or not ev.get(flag) or "replaces" in ev:
            continue
        if step.effect not in best or ev["t_heldout"] > best[step.effect].evidence["t_heldout"]:
            best[step.effect] = step
    return best


def _check_held_back(found: Findings, result: "LoopResult") -> None:
    """An effect that passed every test of the data and was refused only because it moves the
    baseline's physics too far (the Coulomb level lowered beyond ``max_parameter_ratio``, a
    negative mass or viscosity) is either the right effect on a baseline that absorbed something
    else (a Stribeck hump the baseline took into a negative viscous coefficient) or an effect
    that explains friction away: the data alone cannot tell, so the user is shown the effect and
    its strongest held-out evidence."""
    for effect, step in _strongest_refused(result, "held_back_by_plausibility").items():
        ev = step.evidence
        after = ev["moving_rows_error_pct"]["validation"]
        before = after / max(1.0 - ev["validation_gain"], 1e-12)
        why = step.reason.removeprefix("implausible baseline: ")
        found.add("held_back", f"{effect} passed every test of the data (held-out error {before:.3g} -> {after:.3g} % on the {ev['judged_on']}, "
                               f"t = {ev['t_heldout']:.1f}) but was not added, to keep the baseline plausible ({why}): either the baseline had absorbed it "
                               "(a missing Stribeck hump can leave it a negative viscous coefficient) or it explains friction away; "
                               "compare the two models' parameters (the step's in the JSON) before trusting either", effect)


def _check_unconfirmed(found: Findings, result: "LoopResult") -> None:
    """A delay that passed every test on all moving rows and beat a freely timed switch of
    friction, but that the held-out rows clear of reversals and stops support only at the nominal
    level, with less than the minimum gain or (when only nominally significant) less than
    :data:`~gmsfric.loop.select.DELAY_CLEAR_SHARE` of its gain on all rows, looks like a sticking
    contact's lag next to reversals as much as a delay: the loop does not add it, and shows the
    user its timing and evidence (a step or frequency-response test of the drive settles it)."""
    best = _strongest_refused(result, "unconfirmed_clear_of_reversals").get("input_delay")
    if best is None:
        return
    ev = best.evidence
    delay = best.parameters.get("delay_s", {}).get("value", float("nan"))
    found.add("unconfirmed", f"input_delay of {1e3 * delay:.3g} ms passed the held-out tests on all moving rows (gain {100 * ev['validation_gain']:.1f} %, "
                             f"t = {ev['t_heldout']:.1f}; beyond a freely timed switch of friction {100 * ev['validation_gain_beyond_a_free_switch']:.1f} %, "
                             f"t = {ev['t_heldout_beyond_a_free_switch']:.1f}) but on the rows clear of reversals and stops it gains only "
                             f"{100 * ev['validation_gain_away_from_reversals']:.1f} % (t = {ev['t_heldout_away_from_reversals']:.1f}): "
                             "not added, a sticking contact's lag at reversals can look like this; a step or frequency-response test of the drive settles it",
              "input_delay")


def _check_gaps(found: Findings, result: "LoopResult") -> None:
    """Gaps in a log (samples lost): what was made up across them is left out, and said so."""
    parts = []
    for sig in _runs(result):
        n = sig.data.timing.get("gaps", 0)
        if n:
            parts.append(f"{sig.data.source}: {n} gap{'s' if n > 1 else ''} (longest {sig.data.timing['longest_gap_s']:.3g} s, "
                         f"{100.0 * sig.in_gap.mean():.1f} % of the rows left out)")
    if parts:
        found.add("data", f"gaps in the log longer than {GAP_STEPS:g} sample steps, {'; '.join(parts)}: the samples interpolated "
                          f"across a gap and the rows within {GAP_SETTLING_PERIODS:g} filter periods of it are left out of every fit and test",
                  "time")


def _check_wraps(found: Findings, result: "LoopResult") -> None:
    """A rotary position that wrapped around: unwrapped, and the runs put on one turn."""
    parts = []
    for sig in _runs(result):
        timing = sig.data.timing
        n, k = timing.get("turns_unwrapped", 0), timing.get("turns_moved_onto_estimation_travel", 0)
        if n or k:
            parts.append(f"{sig.data.source}: " + ", ".join(([f"{n} whole-turn jump{'s' if n > 1 else ''} unwrapped"] if n else [])
                                                           + ([f"moved by {k:+d} turn{'s' if abs(k) > 1 else ''} onto the estimation run's travel"] if k else [])))
    if parts:
        found.add("data", f"the angle wraps around (an encoder that keeps it within one turn): {'; '.join(parts)}; "
                          "positions are relative to a turn the log does not give", "position")


def _runs(result: "LoopResult") -> list["Signals"]:
    """The estimation run, and the held-out run when it is another."""
    return [result.split.est] + ([result.split.val] if result.split.val is not result.split.est else [])


def _check_travel(found: Findings, result: "LoopResult") -> None:
    """A held-out run that moves beyond the estimation run's travel tests the model where its
    position terms were never fitted."""
    split = result.split
    if split.val is split.est:  # held-out blocks of the estimation run share its travel
        return
    lo, hi = split.est.q_range
    q = split.val.rows["q"][split.val.moving]
    share = float(np.mean((q < lo) | (q > hi))) if q.size else 0.0
    if share > OUTSIDE_TRAVEL:
        unit = "rad" if result.rotary else "m"
        found.add("coverage", f"{100 * share:.0f} % of the held-out run's moving rows lie outside the estimation run's travel "
                              f"({lo:.4g} to {hi:.4g} {unit}): position-dependent terms were fitted on that travel only, and the held-out "
                              "figures there measure extrapolation; record an estimation run over the whole travel", "position")


def check_closed_loop(result: "LoopResult", controller: "PID | Cascade | None" = None) -> Findings:
    """Findings about ``result``'s closed-loop replays (``result.closed_loop`` and
    ``closed_loop_runs``); empty without them.

    Parameters
    ----------
    result : LoopResult
        A loop result whose closed-loop replays were run.
    controller : PID or Cascade, optional
        The replays' controller: its output limits are the drive limits (a cascade's act on
        the drive, after the input disturbance).

    Returns
    -------
    Findings
        ``poor_fit`` (parameter ``closed_loop``) when a replay's force error exceeds
        :data:`CLOSED_LOOP_POOR_PCT`, or :data:`CLOSED_LOOP_FLOOR_PCT` and
        :data:`CLOSED_LOOP_RATIO` times the model's inverse error; ``saturation`` (parameter ``closed_loop``) when a replayed
        drive sits at a finite limit on more than :data:`CLOSED_LOOP_SATURATED` of its samples.
    """
    found = Findings()
    if not result.closed_loop:
        return found
    split = getattr(result, "split", None)
    models = {"baseline": getattr(result, "baseline", None), "final": getattr(result, "final", None)}
    inverse: dict[str, float] = {}
    for mname, model in models.items():
        if split is not None and model is not None and getattr(model, "theta", None) is not None:
            inverse[mname] = float(split.errors_moving(model)[0])
    worst: tuple[float, str, str] | None = None
    for mname, runs in result.closed_loop.items():
        for rname, err in runs.items():
            f = float(err.get("force_pct", np.nan))
            far = f > CLOSED_LOOP_POOR_PCT or (mname in inverse and f > CLOSED_LOOP_FLOOR_PCT and f > CLOSED_LOOP_RATIO * inverse[mname])
            if np.isfinite(f) and far and (worst is None or f > worst[0]):
                worst = (f, mname, rname)
    if worst is not None:
        f, mname, rname = worst
        err = result.closed_loop[mname][rname]
        against = f", against {inverse[mname]:.1f} % for the inverse model on the estimation run" if mname in inverse else ""
        speed = "rad/s" if result.rotary else "m/s"
        if result.split.est.data.gain is not None:
            hint = f"--kv is in command units per {speed}, --kp in 1/s, and --gain and --drive-limit"
        else:  # the drive is the force: a gain in volts per m/s is off by the drive's gain
            force = "N m" if result.rotary else "N"
            hint = (f"--kv is in {'N m s/rad' if result.rotary else 'N s/m'} (the drive is the force: a gain in command units per {speed} "
                    f"is off by the drive's gain), --kp in 1/s, and --drive-limit in {force}")
        found.add("poor_fit", f"the closed-loop replay of the {mname} model on the {rname} run misses the force by {f:.0f} % "
                              f"(acceleration {err.get('acceleration_pct', float('nan')):.0f} %){against}: the simulated loop does not behave "
                              f"like the measured one, so its errors say nothing about the model; check that {hint}, "
                              "and that a run's input disturbance is given (--disturbance)",
                  "closed_loop")
    if controller is not None:
        lo, hi = float(getattr(controller, "u_min", -np.inf)), float(getattr(controller, "u_max", np.inf))
        for (mname, rname), res in result.closed_loop_runs.items():
            u = getattr(res, "command", None)
            if u is None:
                continue
            share = fraction_at_limit(u, lo, hi)
            if share > CLOSED_LOOP_SATURATED:
                found.add("saturation", f"the closed-loop replay of the {mname} model on the {rname} run holds the drive at its limit "
                                        f"on {share:.1%} of the samples: the replay is then the limit's, not the model's "
                                        "(check --drive-limit and the units of --kv)", "closed_loop")
                break
    return found
