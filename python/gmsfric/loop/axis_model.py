"""The loop's force model as an :class:`~gmsfric.axis.AxisModel`: every accepted term becomes
the physics the core simulates in feedback, so the model runs on any trajectory.

====================================  ======================================================
inverse-model term                    in the AxisModel
====================================  ======================================================
``M qdd``                             rigid plant of mass ``M`` (less a compliant load)
``Fv qd + Fc sign(qd) + offset``      static map (viscous, Coulomb, offset)
``stribeck``                          the map's Stribeck curve ``fs = Fc + (Fs - Fc)``
``asymmetric_friction``               per-direction viscous ``Fv +- dFv`` (a constant column: the offset)
``position_dependent_friction``       Coulomb level ``+ g(q)`` (same Legendre/Fourier basis)
``position_dependent_force``          force ``g(q)``
``friction_drift``                    drift ``h(t)`` (linear over the estimation run, or exponential)
``heating``                           heating: levels ``+ dFc m``, ``+ dFv m``, ``m`` the low-passed speed
``presliding_hysteresis``             Maxwell-slip blocks ``k_i = w_i / Delta_i``
``compliance``                        load ``m_load`` on a spring-damper (``fn``, ``zeta``)
``input_delay`` / alignment           the plant's delay: the force's shift less the half sample the
                                      core's hold simulates
====================================  ======================================================
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np

from ..axis import AxisModel, AxisUnits, Compliance, Covariance, Drift, Effects, Heating, PositionSeries
from ..errors import InvalidInputError
from ..models import MaxwellSlip, StaticFriction, Stribeck
from ..system import Plant
from .idim import LinearModel, Signals

#: Stribeck velocity used for a map without a Stribeck term (any value: fs = fc makes it inert).
_FLAT_VS = 1.0


def _series(hyper: tuple, coef: np.ndarray, q_range: tuple[float, float]) -> PositionSeries:
    """The loop's position basis (Legendre degree, or Fourier periods and harmonics) with its
    fitted coefficients."""
    if hyper[0] == 0:
        lo, hi = q_range
        return PositionSeries.legendre(lo, hi, np.concatenate(([0.0], coef)), beyond="linear")
    return PositionSeries.fourier(tuple(hyper[2:]), int(hyper[1]), coef)


def to_axis_model(model: LinearModel, est: Signals, *, gain: float | None = None, kind: str = "linear", provenance: dict[str, Any] | None = None) -> AxisModel:
    """The AxisModel of a fitted loop model.

    Parameters
    ----------
    model : LinearModel
        Fitted on ``est``.
    est : Signals
        The estimation run (its travel defines the position bases, its duration the linear drift).
    gain : float, optional
        Drive gain (N per command unit; N m on a rotary axis) when the runs were given as
        commands (the command unit is then V).  None when they were given as a force: the
        command is then the force itself, the model's command unit N (N m) and its force gain
        1 N/N, never a drive gain the data do not state.
    kind : {"linear", "rotary"}
    provenance : dict, optional

    Non-physical values the core refuses (a negative Coulomb level or viscous coefficient) are
    clamped at zero with a warning: the simulation then shows what the model can do physically.
    """
    if model.theta is None:
        raise InvalidInputError("the model is not fitted")
    theta = dict(zip(model.param_names, model.theta))
    offsets = np.cumsum([0] + [len(t.param_names) for t in model.terms])
    by_term = {t.name: (t, model.theta[offsets[i] : offsets[i + 1]]) for i, t in enumerate(model.terms)}

    def clamp(name: str, value: float) -> float:
        if value < 0:
            warnings.warn(f"{name} = {value:.4g} is negative: simulated as 0", stacklevel=3)
            return 0.0
        return value

    mass = theta.get("M", 0.0)
    effects: dict[str, Any] = {}
    offset = theta.get("offset", 0.0)
    fc = theta.get("Fc", 0.0)
    fs, vs, delta = fc, _FLAT_VS, 1.0
    if "stribeck" in by_term:
        t, c = by_term["stribeck"]
        fs = fc + float(c[0])
        vs, delta = float(t.hyper[0]), float(t.hyper[1])
    if "asymmetric_friction" in by_term:
        t, c = by_term["asymmetric_friction"]
        # the viscous asymmetry; a constant column (the model had no offset) is the offset:
        # while moving, a Coulomb asymmetry and an offset are the same force
        effects["asymmetry"] = (0.0, float(c[0]))
        if len(c) > 1:
            offset += float(c[1])
    if "position_dependent_friction" in by_term:
        t, c = by_term["position_dependent_friction"]
        effects["position_friction"] = _series(t.hyper, c, est.q_range)
    if "position_dependent_force" in by_term:
        t, c = by_term["position_dependent_force"]
        effects["position_force"] = _series(t.hyper, c, est.q_range)
    if "friction_drift" in by_term:
        t, c = by_term["friction_drift"]
        tau_frac = float(t.hyper[0])
        shape, scale = ("linear", est.duration) if tau_frac <= 0 else ("exponential", tau_frac * est.duration)
        effects["drift"] = Drift(shape, scale, float(c[0]), float(c[1]))  # type: ignore[arg-type]
    if "heating" in by_term:
        t, c = by_term["heating"]
        effects["heating"] = Heating(float(t.hyper[0]), float(c[0]), float(c[1]))
    if "presliding_hysteresis" in by_term:
        t, c = by_term["presliding_hysteresis"]
        w = np.clip(c, 0.0, None)
        keep = w > 0
        if keep.any():
            deltas = np.asarray(t.hyper, dtype=float)
            effects["blocks"] = MaxwellSlip(k=w[keep] / deltas[keep], w=w[keep])
    if "compliance" in by_term:
        t, c = by_term["compliance"]
        m_load = float(c[0])
        if 0 < m_load < mass:
            effects["compliance"] = Compliance(m_load, float(t.hyper[0]), float(t.hyper[1]))
            mass -= m_load
        else:
            warnings.warn(f"load mass {m_load:.4g} kg is not within (0, M = {mass:.4g} kg): compliance not simulated", stacklevel=2)
    if mass <= 0:
        raise InvalidInputError(f"the fitted mass M = {mass:.4g} is not positive: the model cannot be simulated")
    delay = max(model.delay - model.extras.get("sampling_hold_s", 0.0), 0.0)
    plant = Plant.from_mass(mass, force_gain=gain if gain is not None else 1.0, delay=delay)
    command = "V"
    if gain is None:
        command = "N m" if kind == "rotary" else "N"
        plant = dataclasses.replace(plant, drive=command)
    friction = StaticFriction(Stribeck(clamp("Fc", fc), clamp("Fs", fs), vs, delta), sigma=clamp("Fv", theta.get("Fv", 0.0)), offset=offset)
    cov = None
    if model.cov is not None and np.all(np.isfinite(model.cov)):
        # The parameters that map one to one onto the AxisModel's (the mass is 1/a: not linear).
        names = {"Fv": "friction.sigma", "Fc": "friction.stribeck.fc", "offset": "friction.offset"}
        idx = [i for i, n in enumerate(model.param_names) if n in names]
        if idx:
            cov = Covariance(tuple(names[model.param_names[i]] for i in idx), model.cov[np.ix_(idx, idx)])
    return AxisModel(plant, friction, Effects(**effects), AxisUnits(kind=kind, command=command), cov, provenance or {})  # type: ignore[arg-type]
