"""Closed-loop simulation of an identified force model on the compiled core.

The rigid body, the delay, viscous and Coulomb friction, the offset and a Stribeck dip are
simulated by the core (:func:`gmsfric.simulate_closed_loop`, friction with stiction).  The other
catalogue effects (asymmetry, position- and time-dependent terms, pre-sliding blocks, the load
resonance) enter as a ``load_force`` evaluated along the measured trajectory; the simulated
axis stays within micrometres of it, so this is the model's force on the simulated path to
within that distance.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy import signal

from ..errors import InvalidInputError
from ..models import StaticFriction, Stribeck
from ..system import PID, Cascade, ClosedLoopResult, Plant, simulate_closed_loop
from .idim import LinearModel, Signals, relative_error

CORE_TERMS = ("inertia", "viscous", "coulomb", "offset", "stribeck")


def _derivatives(q: np.ndarray, sig: Signals) -> tuple[np.ndarray, np.ndarray]:
    b, a = signal.butter(sig.pre.order, sig.cutoff / (sig.fs / 2.0))
    qf = signal.filtfilt(b, a, q)
    return np.gradient(qf, sig.dt), np.gradient(np.gradient(qf, sig.dt), sig.dt)


def simulate_model(model: LinearModel, sig: Signals, controller: PID | Cascade) -> tuple[ClosedLoopResult, dict[str, float]]:
    """Simulate ``model`` in closed loop on the run of ``sig`` and compare with the measurement.

    The run must carry a reference (``AxisData.reference``); its ``disturbance`` (if any) is
    added to the controller output.  Forces are ``gain * command`` (gain 1 when the run gave a
    force column).

    Returns
    -------
    result : ClosedLoopResult
    errors : dict
        Relative errors (%) ``position``, ``velocity``, ``acceleration`` (both signals
        filtered and differentiated the same way) and ``force``.
    """
    d = sig.data
    if d.reference is None:
        raise InvalidInputError(f"{d.source}: a closed-loop simulation needs a reference column")
    p = {k: v["value"] for k, v in model.params().items() if k != "sampling_hold_s"}
    gain = d.gain if d.gain is not None else 1.0
    # the core holds the command over each step already: the sampling-hold alignment is not a delay
    delay = max(model.delay - model.extras.get("sampling_hold_s", 0.0), 0.0)
    plant = Plant.from_mass(max(p["M"], 1e-9), force_gain=gain, delay=delay)
    fc = max(p.get("Fc", 0.0), 0.0)
    fs = fc + max(p.get("Fs_minus_Fc", 0.0), 0.0)
    vs = p.get("vs", 1.0)
    friction = StaticFriction(Stribeck(fc, fs, vs, p.get("stribeck_delta", 1.0)), sigma=max(p.get("Fv", 0.0), 0.0), offset=p.get("offset", 0.0))
    load = np.zeros(len(d))
    assert model.theta is not None
    i = 0
    for t in model.terms:
        k = len(t.param_names)
        if t.name not in CORE_TERMS:
            load += t.full(sig) @ model.theta[i : i + k]
        i += k
    # negative Fc / Fv (clipped above) go to the load as well
    load += min(p.get("Fv", 0.0), 0.0) * sig.qd + min(p.get("Fc", 0.0), 0.0) * np.sign(sig.qd)
    res = simulate_closed_loop(plant, friction, controller, d.reference, sig.dt, input_disturbance=d.disturbance,
                               load_force=load if np.any(load) else None, initial_position=float(d.position[0]))
    v_m, a_m = _derivatives(d.position, sig)
    v_s, a_s = _derivatives(res.position, sig)
    f_meas = d.force
    f_sim = gain * res.command
    errors = {
        "position_pct": relative_error(d.position, res.position),
        "velocity_pct": relative_error(v_m, v_s),
        "acceleration_pct": relative_error(a_m, a_s),
        "force_pct": relative_error(f_meas, f_sim),
    }
    return res, errors


def closed_loop_report(models: dict[str, LinearModel], runs: dict[str, Signals], controller: PID | Cascade) -> tuple[dict[str, Any], dict[tuple[str, str], ClosedLoopResult]]:
    """Closed-loop errors of each model on each run that has a reference."""
    out: dict[str, Any] = {}
    sims: dict[tuple[str, str], ClosedLoopResult] = {}
    for mname, m in models.items():
        out[mname] = {}
        for rname, s in runs.items():
            if s.data.reference is None:
                continue
            res, err = simulate_model(m, s, controller)
            out[mname][rname] = {k: round(v, 4) for k, v in err.items()}
            sims[(mname, rname)] = res
    return out, sims
