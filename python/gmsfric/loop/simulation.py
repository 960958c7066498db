"""The loop's models judged, and refined, by simulation (``gmsfric loop --fit simulation --open-loop``).

* :func:`refine_closed_loop`: the inverse-model fit as the start of a closed-loop output-error
  fit (:func:`gmsfric.output_error.fit_output_error`) on the estimation run: the reference
  through the known controller (and the run's input disturbance), position and command compared.
* :func:`open_loop_rmse`: the nonlinear-benchmark protocol of EMPS: simulate the position from
  the measured command, RMSE after the first 20 samples (m).
* :func:`add_simulation`: a :class:`~gmsfric.loop.results.LoopResult` with both, as a
  :class:`SimulationLoopResult` whose JSON adds ``simulation_fit`` and ``open_loop`` beside the
  loop's fields; with a refinement, ``closed_loop`` describes the refined models.

Every simulation starts where the measurement does, moving at the measured initial velocity.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import units as _units
from ..axis import AxisModel
from ..errors import InvalidInputError
from ..output_error import OutputErrorResult, default_parameters, fit_output_error
from ..system import PID, Cascade, ClosedLoopResult
from .axis_model import to_axis_model
from .closedloop import drive_limited, initial_state, simulate_axis
from .data import AxisData
from .idim import Signals
from .results import LoopResult

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

__all__ = ["OPEN_LOOP_SKIP", "open_loop_rmse", "simulate_open", "refine_closed_loop", "add_simulation", "SimulationLoopResult"]

#: Samples left out at the start of the open-loop score (the benchmark's protocol).
OPEN_LOOP_SKIP = 20


def _command(data: AxisData, axis: AxisModel) -> np.ndarray:
    """The drive command of a run: the command column, or the force through the model's gain."""
    return data.command if data.command is not None else data.force / axis.plant.force_gain


def simulate_open(axis: AxisModel, data: AxisData) -> ClosedLoopResult:
    """``axis`` driven by the run's measured command (open loop), from the measured initial state."""
    q0, v0 = initial_state(data.t, data.position)
    return axis.simulate(data.dt, command=_command(data, axis), initial_position=q0, initial_velocity=v0, record=("position",))


def open_loop_rmse(axis: AxisModel, data: AxisData, skip: int = OPEN_LOOP_SKIP) -> float:
    """RMS error (m; rad on a rotary axis) of the position simulated in open loop from the
    measured command, after the first ``skip`` samples: the EMPS benchmark's score."""
    return _rmse(simulate_open(axis, data), data, skip)


def _rmse(res: ClosedLoopResult, data: AxisData, skip: int = OPEN_LOOP_SKIP) -> float:
    assert res.position is not None
    return float(np.sqrt(np.mean((res.position - data.position)[skip:] ** 2)))


def refine_closed_loop(axis: AxisModel, sig: Signals, controller: PID | Cascade, *, progress: bool | None = None, **options: Any) -> OutputErrorResult:
    """Closed-loop output-error fit of ``axis`` on the run of ``sig``: the reference through
    ``controller`` with the run's input disturbance (a cascade's limits act on the drive, after
    the disturbance: :func:`~gmsfric.loop.closedloop.drive_limited`); position and command compared (equal say,
    see :func:`~gmsfric.output_error.fit_output_error`). The free parameters are
    :func:`~gmsfric.output_error.default_parameters` (inertia, delay, friction levels, every
    present effect's); ``options`` go to the fit."""
    d = sig.data
    if d.reference is None:
        raise InvalidInputError(f"{d.source}: a closed-loop fit needs a reference column")
    options.setdefault("parameters", default_parameters(axis))
    ctrl, limit = drive_limited(controller)
    return fit_output_error(axis, sig.dt, d.position, reference=d.reference, controller=ctrl, measured_command=_command(d, axis),
                            input_disturbance=d.disturbance, drive_limit=limit, progress=progress, **options)


@dataclass
class SimulationLoopResult(LoopResult):
    """A :class:`~gmsfric.loop.results.LoopResult` with simulation scores and, optionally, the
    models refined by closed-loop simulation error.

    JSON fields added beside the loop's: ``simulation_fit`` (when refined: method, the refined
    parameters of ``baseline`` and ``final`` with standard errors, and that ``closed_loop`` and
    the embedded ``gmsfric_model`` describe the refined models) and ``open_loop``
    (``{"baseline": {"estimation_rmse_m", "validation_rmse_m"}, "final": {...}}``).
    """

    refined: dict[str, OutputErrorResult] = field(default_factory=dict, repr=False)
    open_loop: dict[str, dict[str, float | None]] = field(default_factory=dict)
    open_loop_runs: dict[tuple[str, str], tuple[AxisData, ClosedLoopResult]] = field(default_factory=dict, repr=False)

    def _body(self) -> dict[str, Any]:
        body = super()._body()
        if self.refined:
            body["simulation_fit"] = {
                "method": "closed-loop output error on the estimation run (scipy least_squares on core simulations, started from the inverse-model fit)",
                "closed_loop_models": "refined",
                "gmsfric_model": "refined final model",
                **{name: _fit_summary(r) for name, r in self.refined.items()},
            }
        if self.open_loop:
            body["open_loop"] = self.open_loop
        return body

    def axis_model(self) -> AxisModel:
        """The final model as an AxisModel: the refined one when the run was refined."""
        if "final" in self.refined:
            return self.refined["final"].model
        return super().axis_model()

    def table(self) -> str:
        lines = [super().table()]
        if self.refined:
            lines.append("refined by closed-loop simulation error on the estimation run (closed-loop errors above are of the refined models):")
            for name, r in self.refined.items():
                c = r.channels["command"] if "command" in r.channels else next(iter(r.channels.values()))
                lines.append(f"  {name}: command error {c['relative_error_start_pct']:.3f} -> {c['relative_error_pct']:.3f} % "
                             f"({r.n_simulations} simulations{'' if r.converged else ', NOT converged'})")
                for p in r.parameters:
                    lines.append(f"    {p.path:<28}{p.start:>12.6g} -> {p.value:<12.6g} ± {p.std:.3g} {p.unit}")
                for dg in r.diagnostics:
                    lines.append(f"    warning: {dg['message']}")
        if self.open_loop:
            unit = "mm" if not self.rotary else "mrad"
            lines.append(f"open-loop simulation RMSE (position from the measured command, after {OPEN_LOOP_SKIP} samples), {unit}: estimation / validation")
            for name, d in self.open_loop.items():
                shown = ["-" if v is None else format(1e3 * v, ".3f") for v in (d["estimation_rmse_m"], d["validation_rmse_m"])]
                lines.append(f"  {name:<9}{shown[0]} / {shown[1]}")
        return "\n".join(lines)

    def plot(self) -> dict[str, "Figure"]:
        figs = super().plot()
        if self.open_loop_runs:
            from .plots import plot_open_loop

            figs["open_loop"] = plot_open_loop(self.open_loop_runs, rotary=self.rotary)
        for name, r in self.refined.items():
            figs[f"simulation_fit_{name}"] = r.plot()["simulation"]
        return figs


def _fit_summary(r: OutputErrorResult) -> dict[str, Any]:
    d = r.to_dict()
    return {k: d[k] for k in ("parameters", "derived", "channels", "converged", "message", "n_simulations", "diagnostics")}


def add_simulation(result: LoopResult, controller: PID | Cascade | None, *, fit: bool = False, open_loop: bool = False,
                   progress: bool | None = None) -> SimulationLoopResult:
    """The loop's result with its baseline and final models judged by simulation.

    Parameters
    ----------
    result : LoopResult
        From :func:`~gmsfric.loop.run_loop`.
    controller : PID or Cascade, optional
        The runs' controller; needed for ``fit`` and for the closed-loop errors.
    fit : bool
        Refine both models by closed-loop output error on the estimation run
        (:func:`refine_closed_loop`); ``closed_loop`` then reports the refined models.
    open_loop : bool
        Score both models by open-loop simulation (:func:`open_loop_rmse`) on the estimation
        run and on the validation run (``validation_rmse_m`` is ``None`` without a validation
        run: held-out blocks of the estimation run cannot be simulated on their own).
    progress : bool, optional

    Returns
    -------
    SimulationLoopResult
    """
    if fit and controller is None:
        raise InvalidInputError("refining by closed-loop simulation needs the controller (and a reference in the runs)")
    out = SimulationLoopResult(**{f.name: getattr(result, f.name) for f in fields(LoopResult)})
    est = result.split.est
    kind = "rotary" if result.rotary else "linear"
    models = {"baseline": to_axis_model(result.baseline, est, gain=est.data.gain, kind=kind, provenance=result.provenance),
              "final": LoopResult.axis_model(result)}
    has_val = result.split.val is not est
    if fit:
        assert controller is not None
        for name in models:
            out.refined[name] = refine_closed_loop(models[name], est, controller, progress=progress)
            models[name] = out.refined[name].model
        runs = {"estimation": est, **({"validation": result.split.val} if has_val else {})}
        out.closed_loop, out.closed_loop_runs = {}, {}
        for name, axis in models.items():
            out.closed_loop[name] = {}
            for rname, s in runs.items():
                if s.data.reference is None:
                    continue
                res, err = simulate_axis(axis, s, controller)
                out.closed_loop[name][rname] = {k: round(v, 4) for k, v in err.items()}
                out.closed_loop_runs[(name, rname)] = res
    if open_loop:
        for name, axis in models.items():
            scores: dict[str, float | None] = {}
            for key, sig in (("estimation_rmse_m", est), ("validation_rmse_m", result.split.val if has_val else None)):
                if sig is None:
                    scores[key] = None
                    continue
                res = simulate_open(axis, sig.data)
                scores[key] = _rmse(res, sig.data)
                out.open_loop_runs[(name, "estimation" if sig is est else "validation")] = (sig.data, res)
            out.open_loop[name] = scores
    return out
