"""The paper's Section 4.2 scenario: the axis of eq. 1 tracking a 10 mm, 0.01 Hz sinusoid without
friction, with the static map and with GMS (Fig. 14).

Choices (see ``docs/glitch.md``):

* Plant: eq. 1 as identified (``presets.paper_plant``) for all three runs.  Table 3's revised
  parameters compensate the FRF of the *combined* model in the paper's Simulink set-up; they are
  available as :func:`table3_plant` but not the default (the revised static-map plant, B' = 2.40
  1/s, is a lightly damped resonator that makes the comparison one of plants, not of friction).
* Controller: the paper gives none.  :func:`scenario_controller` is ``presets.paper_pid`` with all
  gains divided by 10 (same zeros, ~1 Hz bandwidth, kp = 5e4 V/m): slow enough that the friction
  glitches stand out of the linear tracking error, as they do in Fig. 14.
* Static map: the paper simulated in MATLAB/Simulink, where a static friction map is a
  single-valued function of velocity (Simscape's Translational Friction block is linear below its
  "linear region velocity threshold", default 1e-4 m/s; a velocity lookup table is continuous
  through zero): it cannot stick.  The "static" run therefore uses the paper's map with
  ``v_linear = static_v_linear`` (default :data:`PAPER_STATIC_V_LINEAR` = 1e-4 m/s); the same map
  with true stiction (``v_linear = 0``, the core's default) is run as ``"static_stiction"``.
* The run starts at the sinusoid's zero crossing with the reference velocity, so there is no
  start transient; one period (100 s) contains two reversals.
"""

from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np
from numpy.typing import NDArray

from .. import presets
from .._validate import finite, non_negative, positive
from ..errors import InvalidInputError
from ..models import GMS, FrictionModel, StaticFriction
from ..system import PID, Cascade, ClosedLoopResult, Plant, simulate_closed_loop
from .metrics import glitch_metrics
from .results import ScenarioResult

#: Table 3 as read in docs/glitch.md: (A' mm/(V s^2), B' 1/s, C' 1/s^2) per friction model.
#: Table 3's revised (A', B', C') per model, as read in :class:`gmsfric.presets.Table3Reading`.
PAPER_TABLE3 = {"static": presets.Table3Reading().static, "gms": presets.Table3Reading().gms}

#: Default gains of the glitch scenario (paper_pid / 10), V/m, V/(m s), V s/m, s.
DEFAULT_GAINS = {"kp": 5.0e4, "ki": 2.5e5, "kd": 1.0e2, "tf": 5e-4}

MODELS = ("none", "static", "gms")

#: Extra run of the sinusoid / circle: the paper's static map with true stiction (v_linear = 0).
STICTION = "static_stiction"

#: Linear-region velocity threshold (m/s) of the paper's static map in the glitch scenario: the
#: default of Simscape's Translational Friction block, the paper's MATLAB/Simulink reading.
PAPER_STATIC_V_LINEAR = 1e-4


def paper_static_map(static: StaticFriction | None = None, v_linear: float | None = PAPER_STATIC_V_LINEAR) -> StaticFriction:
    """The static map as the glitch scenario simulates it: ``static`` (default
    ``presets.paper_static_friction()``) with its linear-region threshold set to ``v_linear``
    (m/s; ``0`` = true stiction, ``None`` = keep ``static.v_linear``)."""
    static = presets.paper_static_friction() if static is None else static
    if not isinstance(static, StaticFriction):
        raise InvalidInputError(f"`static` must be a StaticFriction, got {type(static).__name__}")
    if v_linear is None:
        return static
    return dataclasses.replace(static, v_linear=non_negative("static_v_linear", v_linear))


def scenario_controller(
    kp: float = DEFAULT_GAINS["kp"],
    ki: float = DEFAULT_GAINS["ki"],
    kd: float = DEFAULT_GAINS["kd"],
    tf: float = DEFAULT_GAINS["tf"],
    drive_limit: float = presets.PaperReading().drive_limit,
) -> PID:
    """The PID of the glitch scenario (``presets.paper_pid`` / 10 by default).

    Parameters
    ----------
    kp, ki, kd : float
        Gains (V/m, V/(m s), V s/m).
    tf : float
        Derivative filter time constant (s).
    drive_limit : float
        Symmetric output limit (V).

    Returns
    -------
    PID
    """
    lim = positive("drive_limit", drive_limit)
    return PID(kp=kp, ki=ki, kd=kd, tf=tf, u_min=-lim, u_max=lim)


def table3_plant(model: str, reading: presets.PaperReading = presets.PaperReading(), table3: presets.Table3Reading = presets.Table3Reading()) -> Plant:
    """The revised plant of Table 3 for ``model`` (``"static"`` or ``"gms"``) under ``table3``
    (default ``static: A'=19.85, B'=2.40, C'=176.80``; ``gms: A'=180.40, B'=168.40, C'=176.80``)."""
    return table3.plant(model, reading)


def sinusoid_reference(amplitude: float, frequency: float, dt: float, periods: float = 1.0, phase: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """``r(t) = amplitude sin(2 pi frequency t + phase)`` sampled at ``k dt`` over ``periods``.

    Returns
    -------
    t, r : ndarray
    v0 : float
        Reference velocity at ``t = 0`` (m/s), the natural initial velocity.
    """
    amplitude = positive("amplitude", amplitude)
    frequency = positive("frequency", frequency)
    dt = positive("dt", dt)
    periods = positive("periods", periods)
    phase = finite("phase", phase)
    n = int(round(periods / frequency / dt)) + 1
    if n < 3:
        raise InvalidInputError(f"`dt` = {dt} is too coarse for {periods} period(s) at {frequency} Hz")
    t = np.asarray(np.arange(n) * dt, dtype=np.float64)
    w = 2.0 * np.pi * frequency
    return t, np.asarray(amplitude * np.sin(w * t + phase), dtype=np.float64), float(amplitude * w * np.cos(phase))


def run_sinusoid(
    plant: Plant | None = None,
    static: StaticFriction | None = None,
    gms: GMS | None = None,
    controller: PID | Cascade | None = None,
    *,
    amplitude: float = 0.01,
    frequency: float = 0.01,
    dt: float = 1e-4,
    periods: float = 1.0,
    plants: Mapping[str, Plant] | None = None,
    window: tuple[float, float] | None = None,
    drive_limit: float | None = None,
    static_v_linear: float | None = PAPER_STATIC_V_LINEAR,
    stiction: bool = True,
) -> ScenarioResult:
    """The paper's Fig. 14: tracking error without friction, with the static map and with GMS.

    Parameters
    ----------
    plant : Plant, optional
        Default ``presets.paper_plant()``.
    static, gms : friction models, optional
        Defaults ``presets.paper_static_friction()`` and ``presets.paper_gms()``.
    controller : PID or Cascade, optional
        Default :func:`scenario_controller`.
    static_v_linear : float or None
        Linear-region threshold (m/s) the ``"static"`` run gives the static map (default 1e-4 m/s,
        Simscape's default: the paper's Simulink reading; 0 = true stiction); ``None`` keeps
        ``static.v_linear`` as passed.
    stiction : bool
        Also run the static map with true stiction as ``"static_stiction"`` (default True).
    amplitude, frequency : float
        Sinusoid (m, Hz); the paper: 10 mm, 0.01 Hz.
    dt : float
        Step (s).
    periods : float
        Length of the run in periods (reversals at 1/4 and 3/4 of each).
    plants : dict, optional
        Per-model plants overriding ``plant`` (e.g. ``{"static": table3_plant("static")}``);
        ``"static_stiction"`` defaults to the ``"static"`` entry.
    window : (float, float), optional
        Metric window, see :func:`~gmsfric.glitch.metrics.glitch_metrics`.
    drive_limit : float, optional
        Extra drive limit (V) besides the controller's.

    Returns
    -------
    ScenarioResult
        ``metrics[m].height`` is the glitch relative to the linear error of the same plant,
        ``metrics[m].raw_peak_error`` the raw tracking error at the reversals.
    """
    plant = presets.paper_plant() if plant is None else plant
    stiction_map = paper_static_map(static, 0.0)
    static = paper_static_map(static, static_v_linear)
    gms = presets.paper_gms() if gms is None else gms
    controller = scenario_controller() if controller is None else controller
    t, r, v0 = sinusoid_reference(amplitude, frequency, dt, periods)
    models = MODELS + ((STICTION,) if stiction else ())
    frictions: dict[str, FrictionModel | None] = {"none": None, "static": static, "gms": gms, STICTION: stiction_map}
    plants = dict(plants or {})
    for k in plants:
        if k not in MODELS + (STICTION,):
            raise InvalidInputError(f"`plants` keys must be among {MODELS + (STICTION,)}, got {k!r}")
    if "static" in plants and STICTION not in plants:
        plants[STICTION] = plants["static"]
    jobs = []
    for name in models:
        p = plants.get(name, plant)
        jobs.append((name, p, frictions[name]))
    runs: dict[str, ClosedLoopResult] = {}
    baselines: dict[str, NDArray[np.float64]] = {}
    linear_cache: dict[int, NDArray[np.float64]] = {}
    for name, p, fr in jobs:
        res = simulate_closed_loop(p, fr, controller, r, dt, initial_velocity=v0, drive_limit=drive_limit)
        runs[name] = res
        if fr is None:
            linear_cache[id(p)] = res.error
    for name, p, fr in jobs:
        if id(p) not in linear_cache:
            linear_cache[id(p)] = simulate_closed_loop(p, None, controller, r, dt, initial_velocity=v0, drive_limit=drive_limit).error
        baselines[name] = linear_cache[id(p)]
    metrics = {name: glitch_metrics(t, runs[name].error, r, baseline=baselines[name], window=window) for name in models}
    params = {"amplitude_m": amplitude, "frequency_hz": frequency, "dt_s": dt, "periods": periods, "static_v_linear_m_s": static.v_linear}
    return ScenarioResult(runs, baselines, metrics, params)


__all__ = [
    "PAPER_TABLE3",
    "DEFAULT_GAINS",
    "MODELS",
    "STICTION",
    "PAPER_STATIC_V_LINEAR",
    "paper_static_map",
    "ScenarioResult",
    "scenario_controller",
    "table3_plant",
    "sinusoid_reference",
    "run_sinusoid",
]
