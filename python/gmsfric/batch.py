"""Batch simulation: many closed-loop (or friction-only) runs in one call, on all cores.

Parameter sweeps, Monte Carlo over identified uncertainties and controller-gain sweeps are
independent runs: the compiled core spreads them over all cores (rayon) with the GIL released and
returns stacked ``(n_runs, n_samples)`` arrays.  Every run gives exactly (bit for bit) the result
of :func:`gmsfric.simulate_closed_loop` with the same arguments, whatever the number of threads.

>>> from gmsfric.batch import sweep
>>> combos, res = sweep(plant, gms, pid, reference, 1e-4, vary={"controller.kp": [2e5, 5e5, 1e6]})
>>> res.position.shape            # (3, len(reference))

Long batches show progress on stderr (``gmsfric._progress.Progress``); Ctrl-C cancels the runs
that have not started.  ``threads`` limits the worker count (default: every core, or the
``RAYON_NUM_THREADS`` environment variable).
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator, Mapping, Optional, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._progress import Progress
from ._validate import as_array, count, number
from .errors import InvalidInputError
from .models import native_friction
from .system import ClosedLoopResult, Plant, _measured_view, _record_for_core, _rows, axis_of, native_controller, run_inputs

if TYPE_CHECKING:  # pragma: no cover
    from typing_extensions import Unpack

    from .system import RunOptions

__all__ = ["BatchResult", "simulate_batch", "sweep", "grid", "simulate_friction_batch"]

#: Batches of at least this many steps (runs x samples) show progress unless told otherwise.
PROGRESS_MIN_STEPS = 20_000_000
#: Most worker threads a batch may ask for.
MAX_THREADS = 1024


@dataclass(frozen=True)
class BatchResult:
    """Stacked runs: every recorded array but ``t`` has shape ``(n_runs, n_samples)``; outputs
    not recorded are ``None``.

    ``result[i]`` is run ``i`` as a :class:`~gmsfric.system.ClosedLoopResult` (views, no copy).
    """

    t: NDArray[np.float64]
    reference: Optional[NDArray[np.float64]]
    position: Optional[NDArray[np.float64]] = None
    velocity: Optional[NDArray[np.float64]] = None
    measured: Optional[NDArray[np.float64]] = None
    command: Optional[NDArray[np.float64]] = None
    friction: Optional[NDArray[np.float64]] = None
    recorded_error: Optional[NDArray[np.float64]] = None
    n_runs: int = 0

    @property
    def error(self) -> NDArray[np.float64]:
        """Tracking errors ``reference - position`` (m), ``(n_runs, n_samples)``."""
        if self.recorded_error is not None:
            return self.recorded_error
        if self.position is None:
            raise InvalidInputError("the batch recorded neither `error` nor `position`")
        return (0.0 if self.reference is None else self.reference) - self.position

    def __len__(self) -> int:
        return self.n_runs

    def __getitem__(self, i: int) -> ClosedLoopResult:
        if not -self.n_runs <= i < self.n_runs:
            raise IndexError(f"run {i} out of range for {self.n_runs} runs")

        def row(a: Optional[NDArray[np.float64]]) -> Optional[NDArray[np.float64]]:
            return None if a is None else a[i]

        return ClosedLoopResult(
            t=self.t,
            reference=row(self.reference),
            position=row(self.position),
            velocity=row(self.velocity),
            measured=row(self.measured),
            command=row(self.command),
            friction=row(self.friction),
            recorded_error=row(self.recorded_error),
        )

    def __iter__(self) -> Iterator[ClosedLoopResult]:
        return (self[i] for i in range(self.n_runs))


def _as_list(name: str, value: Any, n_runs: int) -> list[Any]:
    if isinstance(value, (list, tuple)):
        if len(value) not in (1, n_runs):
            raise InvalidInputError(f"`{name}` has {len(value)} entries but there are {n_runs} runs: give 1 or one per run")
        return list(value) * (n_runs // len(value)) if len(value) == 1 else list(value)
    return [value] * n_runs


def _n_runs(*values: Any) -> int:
    lengths = {len(v) for v in values if isinstance(v, (list, tuple)) and len(v) != 1}
    if len(lengths) > 1:
        raise InvalidInputError(f"plants, frictions and controllers give different numbers of runs: {sorted(lengths)}")
    return lengths.pop() if lengths else 1


def _progress_callback(enabled: bool | None, label: str, total: int, steps: int) -> tuple[Progress | None, Callable[[int, int], None] | None]:
    show = steps >= PROGRESS_MIN_STEPS if enabled is None else bool(enabled)
    if not show:
        return None, None
    bar = Progress(label, total=total)

    def report(done: int, _total: int) -> None:
        bar.update(done - bar.count)

    return bar, report


def _threads(threads: int | None) -> int | None:
    return None if threads is None else count("threads", threads, minimum=1, maximum=MAX_THREADS)


def simulate_batch(
    plants: Any,
    frictions: Any,
    controllers: Any,
    reference: ArrayLike | None,
    dt: float,
    *,
    threads: int | None = None,
    progress: bool | None = None,
    **options: "Unpack[RunOptions]",
) -> BatchResult:
    """Run many closed (or open) loops at once; arguments as :func:`gmsfric.simulate_closed_loop`.

    Parameters
    ----------
    plants, frictions, controllers
        One object (shared by every run) or a list with one entry per run. A plant may be an
        :class:`~gmsfric.axis.AxisModel` (then its friction entry is ``None``); a friction or
        controller entry may be ``None`` (frictionless, open loop). The number of runs is the
        length of the lists.
    reference : array_like or None
        1-D (shared by every run) or 2-D ``(n_runs, n_samples)``; ``None`` in open loop.
    threads : int, optional
        Worker threads; default every core (or ``RAYON_NUM_THREADS``).
    progress : bool, optional
        Show progress on stderr; default for batches of at least ``PROGRESS_MIN_STEPS`` steps.
    **options
        As :class:`~gmsfric.system.RunOptions`; arrays 1-D (shared) or 2-D (per run).

    Returns
    -------
    BatchResult
        Stacked ``(n_runs, n_samples)`` arrays.

    Raises
    ------
    InvalidInputError, SimulationError
        For the first (lowest-index) failing run, named in the message (``run 3 (of 10) ...``).
    """
    n_runs = _n_runs(plants, frictions, controllers)
    plant_list = _as_list("plants", plants, n_runs)
    friction_list = _as_list("frictions", frictions, n_runs)
    controller_list = _as_list("controllers", controllers, n_runs)
    axes = [axis_of(p, f, (f"plants[{i}]", f"frictions[{i}]")) for i, (p, f) in enumerate(zip(plant_list, friction_list))]
    native_ctrl = [native_controller(c, f"controllers[{i}]") for i, c in enumerate(controller_list)]
    inputs, record, every = run_inputs(reference, n_runs, options, allow_2d=True)
    n = next(a.shape[1] for a in (inputs["reference"], inputs["feedforward"]) if a is not None)
    dt = number("dt", dt)
    bar, report = _progress_callback(progress, "batch runs", n_runs, n_runs * n)
    try:
        out = _gmsfric.simulate(axes, native_ctrl, number("dt", dt), inputs, _record_for_core(record, inputs), every, _threads(threads), report)
        if report is not None:
            report(n_runs, n_runs)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    out = _measured_view(out, record, inputs)
    ref = None if inputs["reference"] is None else np.broadcast_to(inputs["reference"][:, ::every], (n_runs, -(-n // every)))
    t = np.arange(0, n, every, dtype=np.float64) * dt
    return BatchResult(
        t=t,
        reference=ref,
        position=out.get("position"),
        velocity=out.get("velocity"),
        measured=out.get("measured"),
        command=out.get("command"),
        friction=out.get("friction"),
        recorded_error=out.get("error"),
        n_runs=n_runs,
    )


def _replace_path(obj: Any, path: Sequence[str], value: Any) -> Any:
    """``dataclasses.replace`` along a dotted path (``stribeck.fc`` inside a friction model)."""
    if not path:
        return value
    if not dataclasses.is_dataclass(obj) or isinstance(obj, type):
        raise InvalidInputError(f"cannot set `{'.'.join(path)}` on {type(obj).__name__}: not a gmsfric model")
    head, *rest = path
    if head not in {f.name for f in dataclasses.fields(obj)}:
        raise InvalidInputError(f"{type(obj).__name__} has no parameter `{head}`")
    return dataclasses.replace(obj, **{head: _replace_path(getattr(obj, head), rest, value)})


def grid(**axes: Sequence[Any]) -> list[dict[str, Any]]:
    """Cartesian product of parameter axes: ``grid(a=[1, 2], b=[3, 4])`` gives 4 dicts."""
    names = list(axes)
    return [dict(zip(names, combo)) for combo in itertools.product(*(list(axes[k]) for k in names))]


def sweep(
    plant: Plant,
    friction: Any,
    controller: Any,
    reference: ArrayLike,
    dt: float,
    *,
    vary: Mapping[str, Sequence[Any]] | Sequence[Mapping[str, Any]],
    **kwargs: Any,
) -> tuple[list[dict[str, Any]], BatchResult]:
    """Sweep parameters of the plant, friction model and controller in one batch.

    ``vary`` maps dotted names to values, swept as a Cartesian product
    (``{"controller.kp": [...], "friction.stribeck.fc": [...], "plant.delay": [...]}``), or is a
    list of such assignments, one per run (Monte Carlo samples, for instance).  Each run builds
    its models with ``dataclasses.replace`` (so they are validated as usual).  Other keyword
    arguments go to :func:`simulate_batch`.

    Returns the list of assignments (one dict per run) and the :class:`BatchResult`.
    """
    combos = [dict(c) for c in vary] if not isinstance(vary, Mapping) else grid(**vary)
    if not combos:
        raise InvalidInputError("`vary` gives no runs")
    base = {"plant": plant, "friction": friction, "controller": controller}
    plants, frictions, controllers = [], [], []
    for combo in combos:
        objs = dict(base)
        for key, value in combo.items():
            root, *path = key.split(".")
            if root not in objs or not path:
                raise InvalidInputError(f"`vary` key {key!r} must start with 'plant.', 'friction.' or 'controller.'")
            objs[root] = _replace_path(objs[root], path, value)
        plants.append(objs["plant"])
        frictions.append(objs["friction"])
        controllers.append(objs["controller"])
    return combos, simulate_batch(plants, frictions, controllers, reference, dt, **kwargs)


def simulate_friction_batch(
    models: Sequence[Any],
    t: ArrayLike,
    position: ArrayLike,
    *,
    threads: int | None = None,
    progress: bool | None = None,
) -> NDArray[np.float64]:
    """Friction-only simulation of several models along measured trajectories, on all cores.

    ``position`` is 1-D (one trajectory for every model, read without copying) or 2-D (one row
    per model).  Returns the forces ``(n_models, len(t))``; row ``i`` equals
    ``simulate_friction(models[i], t, position[i])``.
    """
    models = list(models)
    if not models:
        raise InvalidInputError("`models` is empty")
    specs = [native_friction(m, f"models[{i}]") for i, m in enumerate(models)]
    if any(s is None for s in specs):
        raise InvalidInputError("`models` must not contain None")
    t_arr = as_array("t", t, min_len=2)
    x = _rows("position", position, len(models), t_arr.size, allow_2d=True)
    bar, report = _progress_callback(progress, "friction runs", len(models), len(models) * t_arr.size)
    try:
        forces = _gmsfric.simulate_friction(specs, t_arr, x, _threads(threads), report)
        if report is not None:
            report(len(models), len(models))
        return forces
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
