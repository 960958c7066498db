"""Output-error identification: fit an :class:`~gmsfric.axis.AxisModel` by its simulation error.

An inverse model (force from measured motion) can predict forces well and still simulate badly;
the benchmark community scores axes by simulation. :func:`fit_output_error` chooses parameters
of an axis model (by their paths, :meth:`AxisModel.parameters`) so that the core's simulation
reproduces a measured run:

* **open loop** (``controller=None``): the drive ``command`` (or the ``force``) is the input,
  the position the output;
* **closed loop**: the ``reference`` is the input, run through the known ``controller`` with the
  known ``input_disturbance``; the position and the controller's ``measured_command`` are the
  outputs, each normalised by its starting error and weighted (``weights``).

The fit is :func:`scipy.optimize.least_squares` (trust-region reflective, bounds) on scaled
parameters: ``log(p / p0)`` for the positive ones (mass, levels, viscous coefficients, ...),
``p / scale`` for signed ones or those starting at zero. Every finite-difference Jacobian is
one :func:`gmsfric.batch.simulate_batch` call (all perturbed models on all cores, recording
only the outputs the cost uses). Standard errors come from the Jacobian, corrected for the
residual's correlation in time (:func:`~gmsfric.identify.results.autocorrelation_inflation`,
per output channel, as a sandwich): simulation residuals are far from white, and the plain
``s^2 (J^T J)^-1`` would be several times too small.

Start from a good model (the loop's inverse-model fit): the simulation error is a non-convex
function of the parameters, and in open loop a flat one (mass against viscous friction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares  # type: ignore[import-untyped, unused-ignore]

from . import units as _units
from ._progress import Progress
from ._validate import count, finite, measured_signal, positive, same_length
from .axis import AxisModel, Covariance, parameter_quantity
from .batch import simulate_batch
from .errors import InvalidInputError, SimulationError
from .identify.results import autocorrelation_inflation, covariance_from_jacobian, transform_covariance
from .models import StaticFriction
from .results import Result, jsonable
from .system import Cascade, Controller, PID, PIDDOB

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["fit_output_error", "default_parameters", "OutputErrorResult", "FittedParameter", "CHANNELS"]

#: Output channels a fit can compare: the position (both modes), the command (closed loop).
CHANNELS = ("position", "command")

# Last path components of parameters that cannot be negative (fitted on a log scale when they
# start above zero, bounded below by zero otherwise).
_POSITIVE = {"a", "b", "c", "delay", "force_gain", "fc", "fs", "vs", "delta", "sigma", "sigma0", "sigma1", "sigma2", "v_linear",
             "k", "w", "alpha", "tau", "scale", "mass", "fn_hz", "zeta"}
#: Blocks of the jackknife behind the standard errors (fewer when the residual is correlated for
#: longer than a twelfth of the run). On the known-truth rigs of the tests, 12 gives z-scores with
#: an RMS of about 1.2 to 1.5 (``benches/emps_research/oe_rig_calibration.py``), 50 blocks twice that.
JACKKNIFE_BLOCKS = 12
#: Integrated autocorrelation time (samples) of a channel's residual above which the fit is
#: reported as missing something systematic.
CORRELATED_RESIDUAL = 10.0
#: Residual value of a parameter set the core refuses or that diverges: far worse than any fit.
_FAILED_RESIDUAL = 1e3


@dataclass(frozen=True)
class FittedParameter:
    """One fitted parameter, SI.

    Attributes
    ----------
    path : str
        As :meth:`AxisModel.parameters`.
    start, value, std : float
        Start value, fitted value, standard error (``inf`` when the data do not determine it).
    lower, upper : float
        Bounds of the fit.
    log : bool
        Fitted as ``log(value / start)`` (a positive parameter) rather than linearly.
    unit : str
        SI unit.
    at_bound : bool
        The fit ended on a bound.
    """

    path: str
    start: float
    value: float
    std: float
    lower: float
    upper: float
    log: bool
    unit: str
    at_bound: bool = False

    @property
    def relative_std(self) -> float:
        """``std / |value|`` (``inf`` at zero)."""
        return self.std / abs(self.value) if self.value != 0 else math.inf

    def as_dict(self) -> dict[str, Any]:
        return {"value": self.value, "std": self.std, "stderr": self.std, "unit": self.unit, "start": self.start,
                "lower": self.lower, "upper": self.upper, "scale": "log" if self.log else "linear", "at_bound": self.at_bound}


@dataclass
class OutputErrorResult(Result):
    """Outcome of :func:`fit_output_error` (the shared result protocol: ``to_dict``, ``table``,
    ``plot``, ``save``).

    Attributes
    ----------
    model : AxisModel
        The fitted model, its covariance over the fitted parameter paths (SI) included.
    start : AxisModel
        The model the fit started from.
    parameters : list of FittedParameter
    mode : {"open_loop", "closed_loop"}
    channels : dict
        Per output channel: ``scale`` (residual normalisation, SI), ``weight``, ``rmse_start``,
        ``rmse`` (SI), ``relative_error_start_pct``, ``relative_error_pct``
        (``100 ||sim - meas|| / ||meas||``), ``inflation`` (the correlation factor applied to
        its variance), ``samples``.
    converged : bool
        ``least_squares`` met a tolerance (not the evaluation limit).
    message : str
    n_simulations : int
        Simulations run, Jacobians included.
    nfev, njev : int
        Cost and Jacobian evaluations.
    t : ndarray
        Time (s) of the compared samples (not in the JSON).
    measured, simulated_start, simulated : dict of ndarray
        Per channel (not in the JSON).
    provenance : dict
    diagnostics : list of dict
        ``{"code", "parameter" or "channel", "message"}``: ``not_converged``, ``at_bound``,
        ``large_std`` (standard error above 100 % of the value), ``undetermined``,
        ``correlated_residual`` (systematic misfit), ``no_improvement``.
    """

    kind = "output_error"

    model: AxisModel
    start: AxisModel
    parameters: list[FittedParameter]
    mode: Literal["open_loop", "closed_loop"]
    channels: dict[str, dict[str, float]]
    converged: bool
    message: str
    n_simulations: int
    nfev: int
    njev: int
    t: NDArray[np.float64] = field(repr=False, default_factory=lambda: np.zeros(0))
    measured: dict[str, NDArray[np.float64]] = field(repr=False, default_factory=dict)
    simulated_start: dict[str, NDArray[np.float64]] = field(repr=False, default_factory=dict)
    simulated: dict[str, NDArray[np.float64]] = field(repr=False, default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    @property
    def values(self) -> dict[str, float]:
        """Fitted values by path (SI)."""
        return {p.path: p.value for p in self.parameters}

    @property
    def stderr(self) -> dict[str, float]:
        """Standard errors by path (SI)."""
        return {p.path: p.std for p in self.parameters}

    def derived(self) -> dict[str, dict[str, Any]]:
        """The moving mass ``force_gain / a`` of a rigid plant when ``plant.a`` was fitted (SI,
        standard error to first order)."""
        p = {q.path: q for q in self.parameters}
        if "plant.a" not in p or self.model.plant.b != 0 or self.model.plant.c != 0:
            return {}
        a = p["plant.a"]
        m = self.model.plant.mass
        quantity = "mass"
        return {"mass": {"value": m, "std": m * a.std / a.value, "unit": _units.si_unit(quantity, self.model.units.kind == "rotary")}}

    def _body(self) -> dict[str, Any]:
        return jsonable({
            "mode": self.mode,
            "parameters": {p.path: p.as_dict() for p in self.parameters},
            "derived": self.derived(),
            "channels": self.channels,
            "converged": self.converged,
            "message": self.message,
            "n_simulations": self.n_simulations,
            "nfev": self.nfev,
            "njev": self.njev,
        })

    def _extras(self) -> dict[str, Any]:
        # `load_model` on this JSON gives the fitted model, covariance included.
        return {"gmsfric_model": self.model.model_document()}

    def table(self) -> str:
        """Parameters (start, fitted ± 1 std) and the error of every channel before and after."""
        rot = self.model.units.kind == "rotary"
        lines = [f"output-error fit ({self.mode.replace('_', ' ')}): {'converged' if self.converged else 'NOT converged'}, "
                 f"{self.n_simulations} simulations ({self.message})"]
        lines.append(f"{'parameter':<30}{'start':>14}{'fitted':>14}{'± std':>12}  unit")
        for p in self.parameters:
            flag = " [at bound]" if p.at_bound else (" [std > 100 %]" if p.relative_std > 1 else "")
            lines.append(f"{p.path:<30}{p.start:>14.6g}{p.value:>14.6g}{p.std:>12.3g}  {p.unit}{flag}")
        for name, d in self.derived().items():
            lines.append(f"{'(' + name + ')':<30}{'':>14}{d['value']:>14.6g}{d['std']:>12.3g}  {d['unit']}")
        for c, d in self.channels.items():
            unit = _units.si_unit("position", rot) if c == "position" else self.model.units.command
            lines.append(f"{c}: RMS error {d['rmse_start']:.4g} -> {d['rmse']:.4g} {unit} "
                         f"({d['relative_error_start_pct']:.3f} -> {d['relative_error_pct']:.3f} %), correlation factor {d['inflation']:.3g}")
        for d in self.diagnostics:
            lines.append(f"warning: {d['message']}")
        return "\n".join(lines)

    def plot(self) -> dict[str, "Figure"]:
        """``simulation``: measured and simulated outputs (start and fit) with their errors;
        ``parameters``: fitted change from the start, ± 2 std."""
        from .plotting import new_figure

        rot = self.model.units.kind == "rotary"
        chans = [c for c in CHANNELS if c in self.measured]
        fig, axes = new_figure(2 * len(chans), 1, figsize=(9.0, 3.0 * len(chans) + 1.5), sharex=True)
        for i, c in enumerate(chans):
            if c == "position":
                unit = _units.display_unit("position", rot)
                k = 1.0 / _units.factor(unit, "position", rotary=rot)
            else:
                unit, k = self.model.units.command, 1.0
            top, bottom = axes[2 * i], axes[2 * i + 1]
            top.plot(self.t, k * self.measured[c], "k", lw=0.8, label="measured")
            top.plot(self.t, k * self.simulated_start[c], lw=0.8, label="start model")
            top.plot(self.t, k * self.simulated[c], lw=0.8, label="fitted model")
            top.set_ylabel(f"{c} [{unit}]")
            top.legend(fontsize="small")
            bottom.plot(self.t, k * (self.simulated_start[c] - self.measured[c]), lw=0.8, label="start model")
            bottom.plot(self.t, k * (self.simulated[c] - self.measured[c]), lw=0.8, label="fitted model")
            bottom.set_ylabel(f"{c} error [{unit}]")
        axes[-1].set_xlabel("time [s]")
        for ax in axes:
            ax.grid(True, alpha=0.3)
        pfig, (ax,) = new_figure(figsize=(7.0, 0.4 * len(self.parameters) + 1.5))
        y = np.arange(len(self.parameters))
        change = [100 * (p.value / p.start - 1) if p.start else 0.0 for p in self.parameters]
        err = [200 * p.std / abs(p.start) if p.start and np.isfinite(p.std) else 0.0 for p in self.parameters]
        ax.errorbar(change, y, xerr=err, fmt="o", capsize=3)
        ax.axvline(0.0, color="k", lw=0.8)
        ax.set_yticks(y, [p.path for p in self.parameters], fontsize="small")
        ax.set_xlabel("fitted change from the start [%] (± 2 std)")
        ax.grid(True, axis="x", alpha=0.3)
        return {"simulation": fig, "parameters": pfig}


# ------------------------------------------------------------------------------------------


def default_parameters(model: AxisModel) -> list[str]:
    """The parameters an output-error fit of ``model`` frees by default: the inertia
    (``plant.a``), the delay, the friction levels and viscous coefficient (the Stribeck curve
    only when it has one, ``fs != fc``), the offset, and every present effect's physical
    parameters (series coefficients, not their travel or periods; blocks; compliance; drift and
    heating levels and time constants). The asymmetry's level is left out beside a static map's
    offset: while moving both are the same constant force.
    """
    if not isinstance(model, AxisModel):
        raise InvalidInputError(f"`model` must be an AxisModel, got {type(model).__name__}")
    p = model.parameters()
    out = ["plant.a", "plant.delay"]
    f = model.friction
    if isinstance(f, StaticFriction):
        out.append("friction.stribeck.fc")
        if f.stribeck.fs != f.stribeck.fc:
            out += ["friction.stribeck.fs", "friction.stribeck.vs"]
        out += ["friction.sigma", "friction.offset"]
    elif f is not None:
        out += [k for k in p if k.startswith("friction.stribeck.") and not k.endswith("delta")]
        out += [k for k in p if k.startswith("friction.") and k.rsplit(".", 1)[-1] in ("sigma", "sigma2")]
    e = model.effects
    if e.asymmetry is not None:
        # While moving, the asymmetry's level acts exactly like the map's offset (+dF in either
        # direction); only stiction tells them apart, so with an offset only their sum is fitted.
        offset = isinstance(f, StaticFriction)
        out += (["effects.asymmetry.1"] if offset else ["effects.asymmetry.0", "effects.asymmetry.1"])
    for name in ("position_force", "position_friction"):
        out += [k for k in p if k.startswith(f"effects.{name}.coef.") or k.startswith(f"effects.{name}.values.")]
    if e.drift is not None:
        out += ["effects.drift.d_level", "effects.drift.d_viscous"]
    if e.heating is not None:
        out += ["effects.heating.tau", "effects.heating.d_level", "effects.heating.d_viscous"]
    if e.blocks is not None:
        out += [k for k in p if k.startswith("effects.blocks.")]
    if e.compliance is not None:
        out += ["effects.compliance.mass", "effects.compliance.fn_hz", "effects.compliance.zeta"]
    return [k for k in out if k in p]


@dataclass
class _Coordinate:
    """Map between a parameter (SI) and the optimiser's scaled coordinate."""

    path: str
    start: float
    log: bool
    scale: float
    lower: float
    upper: float

    def to_x(self, p: float) -> float:
        if self.log:
            return math.log(p / self.start) if p > 0 else -math.inf
        return p / self.scale

    def to_p(self, x: float) -> float:
        return self.start * math.exp(x) if self.log else x * self.scale

    def dp_dx(self, x: float) -> float:
        return self.to_p(x) if self.log else self.scale


def _coordinates(model: AxisModel, paths: Sequence[str], bounds: Mapping[str, tuple[float, float]], scales: Mapping[str, float], dt: float) -> list[_Coordinate]:
    values = model.parameters()
    if len(set(paths)) != len(paths):
        raise InvalidInputError(f"`parameters` names a parameter twice: {sorted(p for p in paths if list(paths).count(p) > 1)}")
    for name, where in (("bounds", bounds), ("scales", scales)):
        extra = [k for k in where if k not in paths]
        if extra:
            raise InvalidInputError(f"`{name}` names parameters that are not fitted: {extra}")
    fc = float(getattr(getattr(model.friction, "stribeck", None), "fc", 0.0) or 0.0)
    sigma = float(getattr(model.friction, "sigma", 0.0) or 0.0)
    out = []
    for path in paths:
        if path not in values:
            raise InvalidInputError(f"`parameters`: the model has no parameter `{path}` (it has {', '.join(values)})")
        p0 = values[path]
        positive_kind = path.rsplit(".", 1)[-1] in _POSITIVE
        lo, hi = bounds.get(path, (0.0 if positive_kind else -math.inf, math.inf))
        lo, hi = float(lo), float(hi)
        if not lo < hi:
            raise InvalidInputError(f"`bounds` of `{path}` must have lower < upper, got ({lo}, {hi})")
        if not lo <= p0 <= hi:
            raise InvalidInputError(f"`{path}` starts at {p0:g}, outside its bounds ({lo:g}, {hi:g})")
        use_log = positive_kind and p0 > 0 and lo >= 0 and path not in scales
        if use_log:
            scale = 1.0
        elif path in scales:
            scale = positive(f"scales[{path!r}]", scales[path])
        elif p0 != 0:
            scale = abs(p0)
        else:
            quantity = parameter_quantity(path)
            guess = {"time": dt, "force": fc, "damping": sigma}.get(quantity, 0.0)
            if not guess > 0:
                raise InvalidInputError(f"`{path}` starts at 0: give its typical size in `scales` (SI)")
            scale = guess
        out.append(_Coordinate(path, p0, use_log, scale, lo, hi))
    return out


def _block_jackknife(jac: Sequence[NDArray[np.float64]], res: Sequence[NDArray[np.float64]], n_blocks: int) -> NDArray[np.float64]:
    """Linearised delete-one-block jackknife covariance of a least-squares fit: channels'
    Jacobians ``jac`` and residuals ``res`` (rows = time), cut into ``n_blocks`` contiguous
    blocks; ``(K-1)/K sum_k (d_k - mean d)(d_k - mean d)^T`` with ``d_k = (A - A_k)^-1 s_k``."""
    rows, p = jac[0].shape
    norms = np.sqrt(sum((j**2).sum(axis=0) for j in jac))
    norms = np.where(norms > 0, norms, 1.0)
    edges = np.linspace(0, rows, n_blocks + 1).astype(int)
    a_k, s_k = [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        jb = [j[lo:hi] / norms for j in jac]
        a_k.append(sum(x.T @ x for x in jb))
        s_k.append(sum(x.T @ r[lo:hi] for x, r in zip(jb, res)))
    a = sum(a_k)
    d = np.array([np.linalg.lstsq(a - ak, sk, rcond=None)[0] for ak, sk in zip(a_k, s_k)])
    d -= d.mean(axis=0)
    cov = (n_blocks - 1) / n_blocks * (d.T @ d)
    return cov / np.outer(norms, norms)


def _channel_array(name: str, value: ArrayLike | None, n: int) -> NDArray[np.float64] | None:
    if value is None:
        return None
    arr = measured_signal(name, value, min_len=2)
    same_length(name, arr, "position", n)
    return arr


def fit_output_error(
    model: AxisModel,
    dt: float,
    position: ArrayLike,
    *,
    command: ArrayLike | None = None,
    force: ArrayLike | None = None,
    reference: ArrayLike | None = None,
    controller: Controller | None = None,
    measured_command: ArrayLike | None = None,
    input_disturbance: ArrayLike | None = None,
    drive_limit: float | tuple[float, float] | None = None,
    parameters: Sequence[str] | None = None,
    bounds: Mapping[str, tuple[float, float]] | None = None,
    scales: Mapping[str, float] | None = None,
    weights: Mapping[str, float] | None = None,
    initial_position: float | None = None,
    initial_velocity: float | None = None,
    skip: int = 0,
    diff_step: float = 1e-4,
    tol: float = 1e-6,
    max_nfev: int = 100,
    horizons: Sequence[float] | None = None,
    threads: int | None = None,
    progress: bool | None = None,
) -> OutputErrorResult:
    """Fit parameters of ``model`` by minimising the error of its simulation on a measured run.

    Parameters
    ----------
    model : AxisModel
        The start (e.g. the loop's inverse-model fit, :meth:`gmsfric.loop.LoopResult.axis_model`).
    dt : float
        Sample step (s) of the run; the core simulates at this step.
    position : array_like
        Measured position (m; rad for a rotary axis), one sample per step: an output.
    command, force : array_like, optional
        Open loop only, one of them: the drive command (input units), or the force on the axis
        (N), turned into a command by the model's ``force_gain``.
    reference : array_like, optional
        Closed loop: the reference position (m); the run starts at the measured position.
    controller : PID, Cascade or PIDDOB, optional
        Closed loop: the known controller (its output limits apply). ``None``: open loop.
    measured_command : array_like, optional
        Closed loop: the measured controller output (input units), a second output.
    input_disturbance : array_like, optional
        Closed loop: known input added to the controller output (input units), e.g. EMPS pulses.
    drive_limit : float or (float, float), optional
        Drive input limits (input units).
    parameters : sequence of str, optional
        Paths of the parameters to fit (:meth:`AxisModel.parameters`); default
        :func:`default_parameters`.
    bounds : mapping, optional
        ``{path: (lower, upper)}`` in SI; positive parameters are bounded below by 0 anyway.
    scales : mapping, optional
        ``{path: typical size}`` (SI): fit that parameter linearly in units of this size. Needed
        for a parameter that starts at 0 and whose size cannot be guessed from the model.
    weights : mapping, optional
        ``{"position": w, "command": w}``: relative weights of the output channels (default 1
        each; 0 drops a channel). Each channel's error is first divided by its RMS error at
        the start, so that equal weights mean equal say.
    initial_position, initial_velocity : float, optional
        Initial state; default ``position[0]`` and the slope of a quadratic fit to the first
        five samples (measured runs may start moving).
    skip : int
        Samples at the start left out of the cost (start-up transients).
    diff_step : float
        Finite-difference step in the scaled coordinates (relative for log parameters).
    tol : float
        ``ftol`` and ``xtol`` of :func:`scipy.optimize.least_squares`.
    max_nfev : int
        Most cost evaluations per stage (each one simulation; Jacobians are counted separately).
    horizons : sequence of float, optional
        Fractions of the run fitted in turn, increasing to 1, each stage started from the
        previous one's result. Default ``(0.125, 0.25, 0.5, 1)`` in open loop, where a poor
        start drifts away and the cost has spurious minima, and ``(1,)`` in closed loop.
    threads : int, optional
        Worker threads of the batch simulations (default: every core).
    progress : bool, optional
        Show progress on stderr (default: when stderr is a terminal).

    Returns
    -------
    OutputErrorResult
        The fitted model (covariance over the fitted paths included), standard errors,
        per-channel errors before and after, diagnostics.

    Raises
    ------
    InvalidInputError
        Before any simulation: unknown parameter paths, inconsistent inputs (a command and a
        force, a controller without a reference, lengths that differ), bad bounds or weights.
    SimulationError
        When the start model itself cannot be simulated on the run.
    """
    if not isinstance(model, AxisModel):
        raise InvalidInputError(f"`model` must be an AxisModel, got {type(model).__name__}")
    dt = positive("dt", dt)
    y = measured_signal("position", position, min_len=10)
    n = y.size
    skip = count("skip", skip, minimum=0, maximum=n - 10)
    diff_step = positive("diff_step", diff_step)
    tol = positive("tol", tol)
    max_nfev = count("max_nfev", max_nfev, minimum=1)
    closed = controller is not None
    if controller is not None and not isinstance(controller, (PID, Cascade, PIDDOB)):
        raise InvalidInputError(f"`controller` must be a PID, Cascade, PIDDOB or None (open loop), got {type(controller).__name__}")
    u = _channel_array("command", command, n)
    f = _channel_array("force", force, n)
    r = _channel_array("reference", reference, n)
    um = _channel_array("measured_command", measured_command, n)
    dist = _channel_array("input_disturbance", input_disturbance, n)
    paths = list(default_parameters(model) if parameters is None else parameters)
    if not paths:
        raise InvalidInputError("`parameters` is empty: nothing to fit")
    if closed:
        if r is None:
            raise InvalidInputError("a closed-loop fit needs the `reference`")
        if u is not None or f is not None:
            raise InvalidInputError("in closed loop the controller makes the command: give `measured_command` (an output), not `command` or `force`")
        feedforward: NDArray[np.float64] | None = None
    else:
        if r is not None or um is not None or dist is not None:
            raise InvalidInputError("`reference`, `measured_command` and `input_disturbance` need a `controller` (closed loop)")
        if (u is None) == (f is None):
            raise InvalidInputError("an open-loop fit needs exactly one input: `command` or `force`")
        if f is not None and "plant.force_gain" in paths:
            raise InvalidInputError("`plant.force_gain` cannot be fitted from a force input (only force / mass matters)")
        feedforward = u if u is not None else np.asarray(f, dtype=np.float64) / model.plant.force_gain
    w = {"position": 1.0, "command": 1.0}
    for k, v in (weights or {}).items():
        if k not in CHANNELS:
            raise InvalidInputError(f"`weights` has an unknown channel {k!r}; the channels are {CHANNELS}")
        w[k] = finite(f"weights[{k!r}]", v)
        if w[k] < 0:
            raise InvalidInputError(f"`weights[{k!r}]` must be >= 0, got {w[k]}")
    measured = {"position": y}
    if um is not None:
        measured["command"] = um
    channels = [c for c in CHANNELS if c in measured and w[c] > 0]
    if not channels:
        raise InvalidInputError("every output channel has weight 0: nothing to compare")
    coords = _coordinates(model, paths, bounds or {}, scales or {}, dt)
    fractions = [0.125, 0.25, 0.5, 1.0] if horizons is None and not closed else [1.0] if horizons is None else [finite("horizons", h) for h in horizons]
    if not fractions or fractions[0] <= 0 or fractions[-1] != 1.0 or any(a >= b for a, b in zip(fractions, fractions[1:])):
        raise InvalidInputError(f"`horizons` must be increasing fractions of the run in (0, 1], ending at 1, got {list(horizons or [])}")
    if initial_position is None or initial_velocity is None:
        from .loop.closedloop import initial_state

        q0, v0 = initial_state(np.arange(n) * dt, y)
    q0 = q0 if initial_position is None else finite("initial_position", initial_position)
    v0 = v0 if initial_velocity is None else finite("initial_velocity", initial_velocity)
    run: dict[str, Any] = dict(initial_position=q0, initial_velocity=v0, drive_limit=drive_limit, record=tuple(channels), threads=threads, progress=False)
    inputs: dict[str, NDArray[np.float64] | None] = {"input_disturbance": dist} if closed else {"feedforward": feedforward}
    horizon = {"stop": n}

    sims = {"n": 0}
    bar = Progress("output-error fit", enabled=True if progress is None else bool(progress))

    def simulate(models: list[AxisModel]) -> dict[str, NDArray[np.float64]]:
        stop = horizon["stop"]
        arrays = {k: v[:stop] for k, v in inputs.items() if v is not None}
        out = simulate_batch(models, None, controller, None if r is None else r[:stop], dt, **run, **arrays)  # type: ignore[arg-type]
        sims["n"] += len(models)
        bar.update(len(models))
        return {c: getattr(out, c)[:, skip:] for c in channels}

    # A flat Stribeck curve (fs = fc) stays flat when only its level is fitted: moving fc alone
    # would leave the break-away force behind and invent a Stribeck dip.
    start_values = model.parameters()
    ties = {}
    for prefix in {p.rsplit(".", 1)[0] for p in paths if p.endswith(".stribeck.fc")}:
        if f"{prefix}.fs" not in paths and start_values.get(f"{prefix}.fs") == start_values[f"{prefix}.fc"]:
            ties[f"{prefix}.fs"] = f"{prefix}.fc"

    def model_at(x: NDArray[np.float64]) -> AxisModel:
        values = {c.path: c.to_p(float(v)) for c, v in zip(coords, x)}
        values.update({dep: values[src] for dep, src in ties.items()})
        return model.with_parameters(values)

    # The start: its simulation fixes each channel's normalisation.
    start_out = simulate([model])
    scale = {}
    for c in channels:
        e = start_out[c][0] - measured[c][skip:]
        rms = float(np.sqrt(np.mean(e**2)))
        scale[c] = rms if rms > 0 else float(np.sqrt(np.mean(measured[c][skip:] ** 2))) or 1.0
    sqrt_w = {c: math.sqrt(w[c]) / scale[c] for c in channels}

    def residual_of(out: Mapping[str, NDArray[np.float64]], i: int) -> NDArray[np.float64]:
        return np.concatenate([sqrt_w[c] * (out[c][i] - measured[c][skip : horizon["stop"]]) for c in channels])

    cache: dict[bytes, NDArray[np.float64]] = {}

    def fun(x: NDArray[np.float64]) -> NDArray[np.float64]:
        key = x.tobytes()
        if key not in cache:
            rows_now = len(channels) * (horizon["stop"] - skip)
            try:
                cache.clear()
                cache[key] = residual_of(simulate([model_at(x)]), 0)
            except (InvalidInputError, SimulationError):
                cache[key] = np.full(rows_now, _FAILED_RESIDUAL)
            bar.update(0, note=f"cost {0.5 * float(cache[key] @ cache[key]) / rows_now:.4g}")
        return cache[key]

    lb = np.array([c.to_x(c.lower) if not (c.log and c.lower <= 0) else -np.inf for c in coords])
    ub = np.array([c.to_x(c.upper) if np.isfinite(c.upper) else np.inf for c in coords])

    def jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        base = fun(x)
        h = diff_step * np.maximum(1.0, np.abs(x))
        h = np.where(x + h > ub, -h, h)  # step away from a bound rather than across it
        shifted = [x + h[i] * np.eye(x.size)[i] for i in range(x.size)]
        try:
            out = simulate([model_at(xi) for xi in shifted])
            cols = [residual_of(out, i) for i in range(x.size)]
        except (InvalidInputError, SimulationError):
            # A perturbed model the core refuses: the columns one at a time, the other side if needed.
            cols = []
            for i in range(x.size):
                col = base
                for sgn in (1.0, -1.0):
                    try:
                        col = residual_of(simulate([model_at(x + sgn * h[i] * np.eye(x.size)[i])]), 0)
                        h[i] *= sgn
                        break
                    except (InvalidInputError, SimulationError):
                        continue
                cols.append(col)
        return np.column_stack([(c - base) / hi for c, hi in zip(cols, h)])

    x0 = np.array([c.to_x(c.start) for c in coords])
    r_start = residual_of(start_out, 0)
    x_stage = x0
    nfev = njev = 0
    try:
        # Growing horizons: a short run keeps a poor start's simulation near the measurement
        # (in open loop an integrator turns every force error into drift, and the cost far from
        # the optimum has minima of its own); each stage starts where the previous one ended.
        for frac in fractions:
            horizon["stop"] = max(skip + 10, int(round(frac * n)))
            cache.clear()
            if horizon["stop"] == n and x_stage is x0:
                cache[x0.tobytes()] = r_start
            sol = least_squares(fun, x_stage, jac=jac, bounds=(lb, ub), method="trf", x_scale=1.0, ftol=tol, xtol=tol, max_nfev=max_nfev)
            x_stage = sol.x
            nfev, njev = nfev + int(sol.nfev), njev + int(sol.njev or 0)
    finally:
        bar.close()

    # Covariance: delete-one-block jackknife, linearised (cluster-robust "CR3"). Simulation
    # residuals are coloured (an integrator drifts; a controller differentiates encoder noise)
    # and a few stretches carry most of the information (a start from rest, the reversals), so
    # neither s^2 (J^T J)^-1, nor that times the autocorrelation time, nor a sandwich of the
    # fitted residuals is honest: the fit has partly absorbed the residual of exactly those
    # stretches. Removing each block of contiguous samples in turn, theta moves by
    # (A - A_k)^-1 s_k (A = J^T J, s_k the block's score J_k^T r_k); the spread of these moves
    # is the variance. Few long blocks (each at least two correlation windows of the slowest
    # channel) keep such a stretch and its correlated aftermath together.
    J = np.asarray(sol.jac)
    rows = n - skip
    p_count = len(coords)
    res_c = [sol.fun[i * rows : (i + 1) * rows] for i in range(len(channels))]
    jac_c = [J[i * rows : (i + 1) * rows] for i in range(len(channels))]
    inflation = {c: autocorrelation_inflation(rc) for c, rc in zip(channels, res_c)}
    window = int(math.ceil(5.0 * max(inflation.values())))  # Sokal's window, c = 5
    n_blocks = int(min(JACKKNIFE_BLOCKS, max(4, rows // (2 * window))))
    # A residual with s^2 = 1 makes covariance_from_jacobian return (J^T J)^-1, inf where undetermined.
    a_inv = covariance_from_jacobian(J, np.array([math.sqrt(max(J.shape[0] - p_count, 1))]))
    good = np.isfinite(np.diag(a_inv))
    cov_x = np.full((p_count, p_count), np.inf)
    if good.any():
        cov_x[np.ix_(good, good)] = _block_jackknife([jc[:, good] for jc in jac_c], res_c, n_blocks)

    cov_p = transform_covariance(cov_x, np.diag([c.dp_dx(float(v)) for c, v in zip(coords, sol.x)]))
    cov_p = 0.5 * (cov_p + cov_p.T)

    rot = model.units.kind == "rotary"
    drive = _units.drive_base(model.units.command, name="units.command")
    fitted_params = []
    diagnostics: list[dict[str, Any]] = []
    for i, (co, xv) in enumerate(zip(coords, sol.x)):
        val = co.to_p(float(xv))
        std = float(math.sqrt(cov_p[i, i])) if np.isfinite(cov_p[i, i]) and cov_p[i, i] >= 0 else math.inf
        on_bound = bool(sol.active_mask[i] != 0)
        fp = FittedParameter(co.path, co.start, val, std, co.lower, co.upper, co.log, _units.si_unit(parameter_quantity(co.path), rot, drive=drive), on_bound)
        fitted_params.append(fp)
        if on_bound:
            diagnostics.append({"code": "at_bound", "parameter": co.path, "message": f"{co.path} ended on a bound ({val:.6g}): the optimum may lie beyond it"})
        if not np.isfinite(std):
            diagnostics.append({"code": "undetermined", "parameter": co.path, "message": f"{co.path} is not determined by this run (singular Jacobian)"})
        elif fp.relative_std > 1 and not on_bound:
            diagnostics.append({"code": "large_std", "parameter": co.path, "message": f"{co.path}: standard error {std:.3g} exceeds its value {val:.3g} (> 100 %)"})
    converged = bool(sol.status > 0)
    if not converged:
        diagnostics.append({"code": "not_converged", "message": f"least_squares stopped without converging: {sol.message}"})
    for c, tau in inflation.items():
        if tau > CORRELATED_RESIDUAL:
            diagnostics.append({"code": "correlated_residual", "channel": c,
                                "message": f"the {c} residual stays correlated over ~{tau:.0f} samples: the model misses something systematic "
                                "(or the fit stopped in a local minimum); the standard errors allow for it"})
    if sol.cost >= 0.5 * float(r_start @ r_start):
        diagnostics.append({"code": "no_improvement", "message": "the fit did not lower the simulation error below the start's"})
    keep = [i for i, p in enumerate(fitted_params) if np.isfinite(p.std)]
    cov = Covariance(tuple(paths[i] for i in keep), cov_p[np.ix_(keep, keep)]) if keep else None
    fit = f"output error ({'closed' if closed else 'open'} loop)"
    best = model_at(sol.x)
    fitted = AxisModel(best.plant, best.friction, best.effects, best.units, cov, {**dict(model.provenance), "fit": fit, "fitted_parameters": paths})
    final_out = {c: v[0] for c, v in simulate([fitted]).items()}
    ch_info = {}
    for c in channels:
        meas = measured[c][skip:]
        e0, e1 = start_out[c][0] - meas, final_out[c] - meas
        norm = float(np.linalg.norm(meas)) or 1.0
        ch_info[c] = {"scale": scale[c], "weight": w[c], "rmse_start": float(np.sqrt(np.mean(e0**2))), "rmse": float(np.sqrt(np.mean(e1**2))),
                      "relative_error_start_pct": 100 * float(np.linalg.norm(e0)) / norm, "relative_error_pct": 100 * float(np.linalg.norm(e1)) / norm,
                      "inflation": inflation[c], "samples": rows}
    return OutputErrorResult(
        model=fitted, start=model, parameters=fitted_params, mode="closed_loop" if closed else "open_loop", channels=ch_info,
        converged=converged, message=str(sol.message), n_simulations=sims["n"], nfev=nfev, njev=njev,
        t=np.asarray((np.arange(n) * dt)[skip:], dtype=np.float64), measured={c: measured[c][skip:] for c in channels}, simulated_start={c: start_out[c][0] for c in channels},
        simulated=final_out, provenance={"fit": fit}, diagnostics=diagnostics,
    )
