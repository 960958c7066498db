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
from typing import Any, Callable, Iterator, Mapping, Optional, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._progress import Progress
from ._validate import as_array, finite, non_negative, positive
from .errors import InvalidInputError
from .models import native_friction
from .system import ClosedLoopResult, Plant, _drive_limits

__all__ = ["BatchResult", "simulate_batch", "sweep", "grid", "simulate_friction_batch"]

#: Batches of at least this many steps (runs x samples) show progress unless told otherwise.
PROGRESS_MIN_STEPS = 20_000_000


@dataclass(frozen=True)
class BatchResult:
    """Stacked closed-loop runs: every array but ``t`` has shape ``(n_runs, n_samples)``.

    ``result[i]`` is run ``i`` as a :class:`~gmsfric.system.ClosedLoopResult` (views, no copy).
    """

    t: NDArray[np.float64]
    reference: NDArray[np.float64]
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    measured: NDArray[np.float64]
    command: NDArray[np.float64]
    friction: NDArray[np.float64]

    @property
    def n_runs(self) -> int:
        return int(self.position.shape[0])

    @property
    def error(self) -> NDArray[np.float64]:
        """Tracking errors ``reference - position`` (m), ``(n_runs, n_samples)``."""
        return self.reference - self.position

    def __len__(self) -> int:
        return self.n_runs

    def __getitem__(self, i: int) -> ClosedLoopResult:
        if not -self.n_runs <= i < self.n_runs:
            raise IndexError(f"run {i} out of range for {self.n_runs} runs")
        return ClosedLoopResult(
            t=self.t,
            reference=self.reference[i],
            position=self.position[i],
            velocity=self.velocity[i],
            measured=self.measured[i],
            command=self.command[i],
            friction=self.friction[i],
        )

    def __iter__(self) -> Iterator[ClosedLoopResult]:
        return (self[i] for i in range(self.n_runs))


def _rows(name: str, values: ArrayLike, n_runs: int, n: int | None = None) -> NDArray[np.float64]:
    """A C-contiguous float64 ``(1 or n_runs, n)`` array; a 1-D input becomes one shared row (a
    view: no copy when it already is contiguous float64)."""
    try:
        arr = np.ascontiguousarray(values, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise InvalidInputError(f"`{name}` must be numeric: {exc}") from None
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2:
        raise InvalidInputError(f"`{name}` must be 1-D (shared by every run) or 2-D (one row per run), got shape {arr.shape}")
    if arr.shape[0] not in (1, n_runs):
        raise InvalidInputError(f"`{name}` has {arr.shape[0]} rows but there are {n_runs} runs: give 1 row or one per run")
    if arr.shape[1] == 0:
        raise InvalidInputError(f"`{name}` is empty")
    if n is not None and arr.shape[1] != n:
        raise InvalidInputError(f"`{name}` has {arr.shape[1]} samples per run but `reference` has {n}: they must match")
    if not np.isfinite(arr).all():
        r, c = np.argwhere(~np.isfinite(arr))[0]
        raise InvalidInputError(f"`{name}` has a non-finite value ({arr[r, c]}) at row {r}, index {c}")
    return arr


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
    if threads is None:
        return None
    if int(threads) != threads or threads < 1:
        raise InvalidInputError(f"`threads` must be a positive integer or None, got {threads!r}")
    return int(threads)


def simulate_batch(
    plants: Plant | Sequence[Plant],
    frictions: Any,
    controllers: Any,
    reference: ArrayLike,
    dt: float,
    *,
    feedforward: ArrayLike | None = None,
    input_disturbance: ArrayLike | None = None,
    load_force: ArrayLike | None = None,
    measurement_noise: ArrayLike | None = None,
    quantization: float = 0.0,
    drive_limit: float | tuple[float, float] | None = None,
    initial_position: float | None = None,
    initial_velocity: float = 0.0,
    threads: int | None = None,
    progress: bool | None = None,
) -> BatchResult:
    """Run many closed loops at once; arguments as :func:`gmsfric.simulate_closed_loop`.

    Parameters
    ----------
    plants, frictions, controllers
        One object (shared by every run) or a list with one entry per run (a friction entry may
        be ``None``: frictionless).  The number of runs is the length of the lists.
    reference : array_like
        1-D (shared by every run) or 2-D ``(n_runs, n_samples)``.
    feedforward, input_disturbance, load_force, measurement_noise : array_like, optional
        1-D (shared) or 2-D (per run), ``n_samples`` long.
    threads : int, optional
        Worker threads; default every core (or ``RAYON_NUM_THREADS``).
    progress : bool, optional
        Show progress on stderr; default for batches of at least ``PROGRESS_MIN_STEPS`` steps.

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
    dt = positive("dt", dt)
    for i, p in enumerate(plant_list):
        if not isinstance(p, Plant):
            raise InvalidInputError(f"`plants[{i}]` must be a Plant, got {type(p).__name__}")
    native_ctrl = []
    for i, c in enumerate(controller_list):
        make = getattr(c, "_native", None)
        if not callable(make):
            raise InvalidInputError(f"`controllers[{i}]` must be a gmsfric controller (PID, Cascade, ...), got {type(c).__name__}")
        native_ctrl.append(make(dt))
    native_fric = [native_friction(f, f"frictions[{i}]") for i, f in enumerate(friction_list)]
    ref = _rows("reference", reference, n_runs)
    n = ref.shape[1]
    optional = {
        name: None if v is None else _rows(name, v, n_runs, n)
        for name, v in (("feedforward", feedforward), ("input_disturbance", input_disturbance), ("load_force", load_force), ("measurement_noise", measurement_noise))
    }
    lo, hi = _drive_limits(drive_limit)
    bar, report = _progress_callback(progress, "batch runs", n_runs, n_runs * n)
    try:
        out = _gmsfric.simulate_closed_loop_batch(
            [p.params for p in plant_list],
            native_fric,
            native_ctrl,
            ref,
            dt,
            optional["feedforward"],
            optional["input_disturbance"],
            optional["load_force"],
            optional["measurement_noise"],
            non_negative("quantization", quantization),
            lo,
            hi,
            None if initial_position is None else finite("initial_position", initial_position),
            finite("initial_velocity", initial_velocity),
            _threads(threads),
            report,
        )
        if report is not None:
            report(n_runs, n_runs)
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
    reference_2d = np.broadcast_to(ref, (n_runs, n))
    return BatchResult(t=np.arange(n) * dt, reference=reference_2d, **out)


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
    t_arr = as_array("t", t, min_len=2)
    x = _rows("position", position, len(models), t_arr.size)
    bar, report = _progress_callback(progress, "friction runs", len(models), len(models) * t_arr.size)
    try:
        forces = _gmsfric.simulate_friction_batch(specs, t_arr, x, _threads(threads), report)
        if report is not None:
            report(len(models), len(models))
        return forces
    finally:
        if bar is not None:
            bar.__exit__(None, None, None)
