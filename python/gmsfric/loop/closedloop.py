"""Closed-loop simulation of an identified force model on the compiled core.

The model becomes an :class:`~gmsfric.axis.AxisModel` (:func:`~gmsfric.loop.axis_model.to_axis_model`):
every accepted effect is simulated in feedback, so the simulated axis follows its own path, not
the measured one. The run starts where the measurement does, moving at the measured initial
velocity (a quadratic fit to the first samples).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from ..axis import AxisModel
from ..errors import InvalidInputError
from ..system import PID, Cascade, ClosedLoopResult
from .axis_model import to_axis_model
from .idim import LinearModel, Signals, relative_error

#: Samples used to estimate the initial velocity.
INITIAL_SAMPLES = 5


def _derivatives(q: np.ndarray, sig: Signals) -> tuple[np.ndarray, np.ndarray]:
    b, a = signal.butter(sig.pre.order, sig.cutoff / (sig.fs / 2.0))
    qf = signal.filtfilt(b, a, q)
    return np.gradient(qf, sig.dt), np.gradient(np.gradient(qf, sig.dt), sig.dt)


def initial_state(t: np.ndarray, q: np.ndarray, n: int = INITIAL_SAMPLES) -> tuple[float, float]:
    """Position and velocity at ``t[0]`` from a quadratic fit to the first ``n`` samples (the
    measured runs may start moving)."""
    n = min(n, q.size)
    if n < 3:
        return float(q[0]), 0.0
    c = np.polyfit(t[:n] - t[0], q[:n], 2)
    return float(q[0]), float(c[1])


def drive_limited(controller: PID | Cascade) -> tuple[PID | Cascade, tuple[float, float] | None]:
    """A cascade's output limits as the drive's: ``(unlimited cascade, (low, high))``.

    The limit of a measured axis is the drive's, and an input disturbance (EMPS's pulses) is
    added to the controller output *before* it: limiting the controller output first would clip
    ``-15 V + 5 V`` to ``-5 V`` instead of ``-10 V``. A PID keeps its limits (its anti-windup
    depends on them)."""
    if isinstance(controller, Cascade) and (np.isfinite(controller.u_min) or np.isfinite(controller.u_max)):
        return Cascade(controller.kp, controller.kv), (controller.u_min, controller.u_max)
    return controller, None


def simulate_model(model: LinearModel, sig: Signals, controller: PID | Cascade, est: Signals | None = None) -> tuple[ClosedLoopResult, dict[str, float]]:
    """Simulate ``model`` in closed loop on the run of ``sig`` and compare with the measurement.

    The run must carry a reference (``AxisData.reference``); its ``disturbance`` (if any) is
    added to the controller output.  Forces are ``gain * command`` (gain 1 when the run gave a
    force column). ``est`` is the run the model was fitted on (default ``sig``).

    Returns
    -------
    result : ClosedLoopResult
    errors : dict
        Relative errors (%) ``position``, ``velocity``, ``acceleration`` (both signals
        filtered and differentiated the same way) and ``force``.
    """
    base = est if est is not None else sig
    return simulate_axis(to_axis_model(model, base, gain=base.data.gain, kind="rotary" if base.data.rotary else "linear"), sig, controller)


def simulate_axis(axis: AxisModel, sig: Signals, controller: PID | Cascade) -> tuple[ClosedLoopResult, dict[str, float]]:
    """Simulate ``axis`` in closed loop on the run of ``sig`` (its reference and input
    disturbance; a cascade's limits on the drive, :func:`drive_limited`), from the measured
    initial state, and compare with the measurement: errors as :func:`simulate_model`."""
    d = sig.data
    if d.reference is None:
        raise InvalidInputError(f"{d.source}: a closed-loop simulation needs a reference column")
    gain = d.gain if d.gain is not None else 1.0
    q0, v0 = initial_state(d.t, d.position)
    ctrl, limit = drive_limited(controller)
    res = axis.simulate(sig.dt, reference=d.reference, controller=ctrl, input_disturbance=d.disturbance, drive_limit=limit,
                        initial_position=q0, initial_velocity=v0, record=("position", "command"))
    assert res.position is not None and res.command is not None
    v_m, a_m = _derivatives(d.position, sig)
    v_s, a_s = _derivatives(res.position, sig)
    ok = sig.observed  # not what a resampling made up across a gap in the log
    errors = {
        "position_pct": relative_error(d.position[ok], res.position[ok]),
        "velocity_pct": relative_error(v_m[ok], v_s[ok]),
        "acceleration_pct": relative_error(a_m[ok], a_s[ok]),
        "force_pct": relative_error(d.force[ok], gain * res.command[ok]),
    }
    return res, errors


def closed_loop_report(models: dict[str, LinearModel], runs: dict[str, Signals], controller: PID | Cascade) -> tuple[dict[str, Any], dict[tuple[str, str], ClosedLoopResult]]:
    """Closed-loop errors of each model on each run that has a reference (the models fitted on
    the first run)."""
    out: dict[str, Any] = {}
    sims: dict[tuple[str, str], ClosedLoopResult] = {}
    est = next(iter(runs.values()))
    for mname, m in models.items():
        out[mname] = {}
        for rname, s in runs.items():
            if s.data.reference is None:
                continue
            res, err = simulate_model(m, s, controller, est)
            out[mname][rname] = {k: round(v, 4) for k, v in err.items()}
            sims[(mname, rname)] = res
    return out, sims
