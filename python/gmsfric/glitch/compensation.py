"""Model-based friction feedforward (the paper's future work) and sweeps over gains.

The *true* axis is the plant with GMS friction (the richer model stands in for the machine).
The feedforward is the friction a model predicts along the reference, in drive units:

* static map: ``F_static(dr/dt) / force_gain`` (reference velocity, ``numpy.gradient``);
* GMS: ``simulate_friction(gms, t, r) / force_gain`` along the reference position;

time-shifted by ``advance`` seconds (default: the plant's input delay, so the force arrives when
the friction acts) and scaled by ``gain``.

The static map of ``"static_feedforward"`` is the paper's map as the glitch scenario reads it
(linear region below ``static_v_linear`` = 1e-4 m/s, the Simulink reading); the true-stiction
map's feedforward (a sign switch of the full 2 Fc at the reference reversal) is the extra
``"static_feedforward_stiction"``.  ``"dob"`` is no feedforward but a disturbance observer on the
PID (:class:`gmsfric.system.PIDDOB`, nominal plant = the plant, Q-filter cutoff ``dob_cutoff_hz``).
"""

from __future__ import annotations

import itertools
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .. import presets
from .._validate import as_array, finite, same_length
from ..errors import InvalidInputError
from ..models import GMS, FrictionModel, StaticFriction, simulate_friction
from ..system import PID, PIDDOB, Cascade, ClosedLoopResult, Controller, Plant, simulate_closed_loop
from .metrics import glitch_metrics
from .results import CompensationResult
from .scenario import DEFAULT_GAINS, PAPER_STATIC_V_LINEAR, paper_static_map, scenario_controller, sinusoid_reference

#: The issue's contract strategies (always run).
STRATEGIES = ("none", "static_feedforward", "gms_feedforward")

#: Extra strategies run by default by :func:`run_compensation`: feedforward from the true-stiction
#: static map, and PID + disturbance observer (no feedforward).
EXTRA_STRATEGIES = ("static_feedforward_stiction", "dob")

#: Default Q-filter cutoff (Hz) of the disturbance observer.
DOB_CUTOFF_HZ = 20.0


def friction_feedforward(
    model: FrictionModel,
    t: ArrayLike,
    reference: ArrayLike,
    force_gain: float,
    *,
    advance: float = 0.0,
    gain: float = 1.0,
) -> NDArray[np.float64]:
    """Friction feedforward (drive units) from ``model`` evaluated along the reference.

    Parameters
    ----------
    model : StaticFriction or dynamic friction model
        A ``StaticFriction`` is evaluated at the reference velocity; any other model is simulated
        along the reference position with :func:`gmsfric.simulate_friction`.
    t : array_like
        Sample times (s), strictly increasing.
    reference : array_like
        Reference position (m).
    force_gain : float
        Plant force per drive unit (N/unit).
    advance : float
        Time shift (s): the feedforward at ``t`` uses the reference at ``t + advance`` (held at
        the last sample beyond the end).  Use the input delay to pre-compensate it.
    gain : float
        Multiplier of the feedforward (1 = the model's force).

    Returns
    -------
    ndarray
        Feedforward per sample (drive units).
    """
    t_arr = as_array("t", t, min_len=3)
    r = as_array("reference", reference, min_len=3)
    same_length("reference", r, "t", t_arr.size)
    advance = finite("advance", advance)
    gain = finite("gain", gain)
    fg = finite("force_gain", force_gain)
    if fg <= 0:
        raise InvalidInputError(f"`force_gain` must be > 0, got {fg}")
    ts = t_arr + advance
    rs = np.interp(ts, t_arr, r)
    if isinstance(model, StaticFriction):
        force = model.force(np.gradient(rs, t_arr))
    else:
        force = simulate_friction(model, t_arr, rs)
    return gain * force / fg


def _simulate_many(jobs: Sequence[Mapping[str, Any]]) -> list[ClosedLoopResult]:
    """The single entry point every sweep goes through: a list of closed-loop jobs (keyword
    arguments of :func:`gmsfric.simulate_closed_loop`) -> results, in order.

    Jobs that share their reference, step and initial state run as one
    :func:`gmsfric.batch.simulate_batch` call (all cores, GIL released); their plants,
    frictions, controllers and feedforwards may differ per run."""
    from ..batch import simulate_batch

    shared = ("reference", "dt", "initial_position", "initial_velocity", "drive_limit", "quantization")
    groups: dict[tuple[Any, ...], list[int]] = {}
    for i, job in enumerate(jobs):
        unknown = set(job) - set(shared) - {"plant", "friction", "controller", "feedforward"}
        if unknown:
            raise InvalidInputError(f"unsupported job keys for a batch: {sorted(unknown)}")
        key = tuple(id(job.get(k)) if k == "reference" else job.get(k) for k in shared)
        groups.setdefault(key, []).append(i)
    results: list[ClosedLoopResult | None] = [None] * len(jobs)
    for members in groups.values():
        first = jobs[members[0]]
        n = np.asarray(first["reference"]).size
        ffs = [jobs[i].get("feedforward") for i in members]
        feedforward = None if all(f is None for f in ffs) else np.stack([np.zeros(n) if f is None else np.asarray(f, dtype=float) for f in ffs])
        batch = simulate_batch(
            [jobs[i]["plant"] for i in members],
            [jobs[i].get("friction") for i in members],
            [jobs[i]["controller"] for i in members],
            first["reference"],
            first["dt"],
            feedforward=feedforward,
            **{k: first[k] for k in shared[2:] if first.get(k) is not None},
        )
        for row, i in enumerate(members):
            results[i] = batch[row]
    return [r for r in results if r is not None]


def run_compensation(
    plant: Plant | None = None,
    true_friction: FrictionModel | None = None,
    static: StaticFriction | None = None,
    gms: GMS | None = None,
    controller: PID | Cascade | None = None,
    *,
    amplitude: float = 0.01,
    frequency: float = 0.01,
    dt: float = 1e-4,
    periods: float = 1.0,
    advance: float | None = None,
    ff_gain: float = 1.0,
    window: tuple[float, float] | None = None,
    static_v_linear: float | None = PAPER_STATIC_V_LINEAR,
    extras: Sequence[str] = EXTRA_STRATEGIES,
    dob_cutoff_hz: float = DOB_CUTOFF_HZ,
) -> CompensationResult:
    """Simulate the sinusoid scenario on the true axis without compensation, with static-map and
    with GMS feedforward.

    Parameters
    ----------
    plant : Plant, optional
        Default ``presets.paper_plant()``.
    true_friction : friction model, optional
        Friction of the simulated machine; default ``gms`` (the identified GMS).
    static, gms : friction models, optional
        The models the feedforwards are computed from (paper defaults).
    controller : PID or Cascade, optional
        Default :func:`~gmsfric.glitch.scenario.scenario_controller`.
    amplitude, frequency, dt, periods : float
        Sinusoid and step as in :func:`~gmsfric.glitch.scenario.run_sinusoid`.
    advance : float, optional
        Feedforward time advance (s); default the plant's input delay.
    ff_gain : float
        Feedforward gain (1 = model force).
    window : (float, float), optional
        Metric window.
    static_v_linear : float or None
        Linear-region threshold (m/s) of the static map behind ``"static_feedforward"`` (default
        1e-4 m/s, the scenario's Simulink reading; 0 = true stiction; None = ``static`` as given).
    extras : sequence of str
        Extra strategies from :data:`EXTRA_STRATEGIES` (``"dob"`` needs a PID controller).
    dob_cutoff_hz : float
        Q-filter cutoff of the disturbance observer (Hz).

    Returns
    -------
    CompensationResult
        The baseline of every strategy is the frictionless run of ``controller`` (the DOB's
        target: it is transparent without disturbance, after its start transient).
    """
    plant = presets.paper_plant() if plant is None else plant
    stiction_map = paper_static_map(static, 0.0)
    static = paper_static_map(static, static_v_linear)
    gms = presets.paper_gms() if gms is None else gms
    true_friction = gms if true_friction is None else true_friction
    controller = scenario_controller() if controller is None else controller
    extras = tuple(extras)
    for k in extras:
        if k not in EXTRA_STRATEGIES:
            raise InvalidInputError(f"`extras` must be among {EXTRA_STRATEGIES}, got {k!r}")
    if "dob" in extras and not isinstance(controller, PID):
        raise InvalidInputError(f"`extras` 'dob' needs a PID `controller`, got {type(controller).__name__}")
    adv = plant.delay if advance is None else finite("advance", advance)
    t, r, v0 = sinusoid_reference(amplitude, frequency, dt, periods)
    ffs: dict[str, NDArray[np.float64] | None] = {
        "none": None,
        "static_feedforward": friction_feedforward(static, t, r, plant.force_gain, advance=adv, gain=ff_gain),
        "gms_feedforward": friction_feedforward(gms, t, r, plant.force_gain, advance=adv, gain=ff_gain),
    }
    if "static_feedforward_stiction" in extras:
        ffs["static_feedforward_stiction"] = friction_feedforward(stiction_map, t, r, plant.force_gain, advance=adv, gain=ff_gain)
    controllers: dict[str, Controller] = {k: controller for k in ffs}
    if "dob" in extras:
        ffs["dob"] = None
        controllers["dob"] = PIDDOB(controller, plant, dob_cutoff_hz)  # type: ignore[arg-type]
    names = list(ffs)
    jobs: list[dict[str, Any]] = [dict(plant=plant, friction=None, controller=controller, reference=r, dt=dt, initial_velocity=v0)]
    jobs += [dict(plant=plant, friction=true_friction, controller=controllers[k], reference=r, dt=dt, initial_velocity=v0, feedforward=ffs[k]) for k in names]
    results = _simulate_many(jobs)
    base = results[0].error
    runs = dict(zip(names, results[1:]))
    metrics = {k: glitch_metrics(t, runs[k].error, r, baseline=base, window=window) for k in names}
    return CompensationResult(runs, ffs, base, metrics, plant.force_gain)


def compensation_sweep(
    grid: Mapping[str, Iterable[float]],
    *,
    plant: Plant | None = None,
    true_friction: FrictionModel | None = None,
    static: StaticFriction | None = None,
    gms: GMS | None = None,
    amplitude: float = 0.01,
    frequency: float = 0.01,
    dt: float = 2e-4,
    periods: float = 1.0,
    tf: float = DEFAULT_GAINS["tf"],
    drive_limit: float = presets.PaperReading().drive_limit,
    window: tuple[float, float] | None = None,
    static_v_linear: float | None = PAPER_STATIC_V_LINEAR,
    strategies: Sequence[str] = STRATEGIES,
) -> list[dict[str, float | str]]:
    """Glitch height of every strategy over a grid of controller and feedforward gains, all runs
    submitted in one batch call.

    Parameters
    ----------
    grid : dict
        Values to combine (Cartesian product) for any of ``kp``, ``ki``, ``kd`` (controller),
        ``ff_gain`` (feedforward multiplier), ``advance`` (feedforward advance, s) and
        ``dob_cutoff_hz`` (observer Q-filter cutoff, Hz; used by ``"dob"``).  Missing keys take the
        scenario defaults (gain 1, advance = plant delay, cutoff :data:`DOB_CUTOFF_HZ`).
    plant, true_friction, static, gms, amplitude, frequency, dt, periods, tf, drive_limit, window, static_v_linear
        As in :func:`run_compensation`.
    strategies : sequence of str
        Among :data:`STRATEGIES` and :data:`EXTRA_STRATEGIES`; ``"none"`` is always run.

    Returns
    -------
    list of dict
        One row per grid point and strategy: the grid values, ``strategy``, ``peak_error_m`` (glitch
        height against the linear error), ``raw_peak_error_m``, ``duration_s``, ``area_m_s`` and ``reduction_percent`` (against the
        uncompensated run at the same controller gains).  Identical runs (e.g. ``"none"`` at every
        ``ff_gain``) are simulated once.
    """
    allowed = ("kp", "ki", "kd", "ff_gain", "advance", "dob_cutoff_hz")
    if not isinstance(grid, Mapping):
        raise InvalidInputError(f"`grid` must be a dict of parameter -> values, got {type(grid).__name__}")
    for k in grid:
        if k not in allowed:
            raise InvalidInputError(f"`grid` key {k!r} is unknown; use {allowed}")
    names = ["none"] + [s for s in dict.fromkeys(strategies) if s != "none"]
    for s in names:
        if s not in STRATEGIES + EXTRA_STRATEGIES:
            raise InvalidInputError(f"`strategies` must be among {STRATEGIES + EXTRA_STRATEGIES}, got {s!r}")
    plant = presets.paper_plant() if plant is None else plant
    stiction_map = paper_static_map(static, 0.0)
    static = paper_static_map(static, static_v_linear)
    gms = presets.paper_gms() if gms is None else gms
    true_friction = gms if true_friction is None else true_friction
    defaults = {"kp": DEFAULT_GAINS["kp"], "ki": DEFAULT_GAINS["ki"], "kd": DEFAULT_GAINS["kd"], "ff_gain": 1.0, "advance": plant.delay,
                "dob_cutoff_hz": DOB_CUTOFF_HZ}
    axes = {k: [finite(f"grid[{k!r}]", v) for v in as_array(f"grid[{k!r}]", list(grid.get(k, [defaults[k]])))] for k in allowed}
    t, r, v0 = sinusoid_reference(amplitude, frequency, dt, periods)
    ff_models: dict[str, FrictionModel] = {"static_feedforward": static, "gms_feedforward": gms, "static_feedforward_stiction": stiction_map}
    ff_cache: dict[tuple[str, float, float], NDArray[np.float64]] = {}

    def ff(name: str, g: float, adv: float) -> NDArray[np.float64]:
        key = (name, g, adv)
        if key not in ff_cache:
            ff_cache[key] = friction_feedforward(ff_models[name], t, r, plant.force_gain, advance=adv, gain=g)
        return ff_cache[key]

    points = [dict(zip(allowed, combo)) for combo in itertools.product(*(axes[k] for k in allowed))]
    jobs: list[dict[str, Any]] = []
    job_of: dict[tuple[Any, ...], int] = {}

    def submit(key: tuple[Any, ...], controller: Controller, friction: FrictionModel | None, feedforward: NDArray[np.float64] | None = None) -> int:
        if key not in job_of:
            job_of[key] = len(jobs)
            jobs.append(dict(plant=plant, friction=friction, controller=controller, reference=r, dt=dt, initial_velocity=v0, feedforward=feedforward))
        return job_of[key]

    which: list[dict[str, int]] = []
    for p in points:
        gains = (p["kp"], p["ki"], p["kd"])
        ctrl = scenario_controller(p["kp"], p["ki"], p["kd"], tf, drive_limit)
        idx = {"linear": submit(("linear", gains), ctrl, None)}
        for s in names:
            if s == "none":
                idx[s] = submit((s, gains), ctrl, true_friction)
            elif s == "dob":
                idx[s] = submit((s, gains, p["dob_cutoff_hz"]), PIDDOB(ctrl, plant, p["dob_cutoff_hz"]), true_friction)
            else:
                idx[s] = submit((s, gains, p["ff_gain"], p["advance"]), ctrl, true_friction, ff(s, p["ff_gain"], p["advance"]))
        which.append(idx)
    results = _simulate_many(jobs)
    rows: list[dict[str, float | str]] = []
    for p, idx in zip(points, which):
        base = results[idx["linear"]].error
        ms = {s: glitch_metrics(t, results[idx[s]].error, r, baseline=base, window=window) for s in names}
        h0 = ms["none"].height
        for s in names:
            m = ms[s]
            row: dict[str, float | str] = dict(p)
            row.update(strategy=s, peak_error_m=m.height, raw_peak_error_m=m.raw_peak_error, duration_s=m.duration, area_m_s=m.area,
                       reduction_percent=(100.0 * (1.0 - m.height / h0)) if h0 > 0 else float("nan"))
            rows.append(row)
    return rows


__all__ = ["STRATEGIES", "EXTRA_STRATEGIES", "DOB_CUTOFF_HZ", "CompensationResult", "friction_feedforward", "run_compensation", "compensation_sweep"]
