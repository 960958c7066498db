"""Batch simulation: many closed-loop (or friction-only) runs in one call, on all cores, or on
a cluster.

Parameter sweeps, Monte Carlo over identified uncertainties and controller-gain sweeps are
independent runs: the compiled core spreads them over all cores (rayon) with the GIL released and
returns stacked ``(n_runs, n_samples)`` arrays.  Runs ``8j .. 8j+7`` (:data:`LANES`) of the same
structure (GMS friction, PID, same plant, step and length, nothing per sample but the reference)
are advanced together in one SIMD vector group; they agree with :func:`gmsfric.simulate_closed_loop` to rounding
(within 1e-12 of the position range, tested), every other run bit for bit.  Results never depend
on the number of threads, nor on ``executor=`` (chunks of whole groups of :data:`LANES` runs, each running
the compiled batch on a worker: any :class:`concurrent.futures.Executor`, e.g. a
``dask.distributed.Client(...).get_executor()``).

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
from .errors import InvalidInputError, SimulationError
from .models import native_friction
from .system import ClosedLoopResult, Plant, _measured_view, _record_for_core, _rows, axis_of, native_controller, run_inputs

if TYPE_CHECKING:  # pragma: no cover
    from concurrent.futures import Executor

    from typing_extensions import Unpack

    from .system import RunOptions

__all__ = ["BatchResult", "simulate_batch", "sweep", "grid", "simulate_friction_batch"]

#: Batches of at least this many steps (runs x samples) show progress unless told otherwise.
PROGRESS_MIN_STEPS = 20_000_000
#: Most worker threads a batch may ask for.
MAX_THREADS = 1024
#: Runs per SIMD vector group in the core: executor chunks are whole multiples of it.
LANES: int = _gmsfric.LANES


@dataclass(frozen=True)
class BatchResult:
    """Stacked runs: every recorded array but ``t`` has shape ``(n_runs, n_samples)``; outputs
    not recorded are ``None``.

    ``result[i]`` is run ``i`` as a :class:`~gmsfric.system.ClosedLoopResult` (views, no copy).
    ``dt`` is the step (s) and ``every`` the decimation of the recorded samples.
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
    dt: float = float("nan")
    every: int = 1

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
            dt=self.dt,
            every=self.every,
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
    executor: "Executor | None" = None,
    chunk_size: int | None = None,
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
    executor : concurrent.futures.Executor, optional
        Run the batch in chunks on this executor's workers (a process pool, or a Dask cluster's
        ``client.get_executor()``); each chunk runs the compiled batch there with ``threads``.
        Models, options and results travel by pickle. Results are those of the local run, in
        order.
    chunk_size : int, optional
        Runs per chunk with ``executor`` (rounded up to a multiple of 4); default: the runs in
        about 64 chunks.
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
        if executor is None:
            out = _gmsfric.simulate(axes, native_ctrl, dt, inputs, _record_for_core(record, inputs), every, _threads(threads), report)
        else:
            out = _on_executor(executor, _chunks(n_runs, chunk_size), plant_list, friction_list, controller_list, reference, dt, options, threads, report)
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
        dt=dt,
        every=every,
    )


def _chunks(n_runs: int, chunk_size: int | None) -> list[tuple[int, int]]:
    """``[start, stop)`` ranges of whole groups of :data:`LANES` runs (the core's SIMD groups
    never straddle a multiple of it, so each chunk computes what the whole batch computes)."""
    size = -(-n_runs // 64) if chunk_size is None else count("chunk_size", chunk_size, minimum=1)
    size = -(-size // LANES) * LANES
    return [(a, min(a + size, n_runs)) for a in range(0, n_runs, size)]


def _per_run(value: Any, a: int, b: int, n_runs: int) -> Any:
    """Rows ``a:b`` of a 2-D per-run array (one row per run); shared values pass unchanged."""
    if isinstance(value, np.ndarray) and value.ndim == 2 and value.shape[0] == n_runs and n_runs > 1:
        return value[a:b]
    return value


def _batch_chunk(plants: Any, frictions: Any, controllers: Any, reference: Any, dt: float, options: dict[str, Any], threads: int | None) -> dict[str, NDArray[np.float64]]:
    """One chunk of an executor batch, on a worker: the compiled batch, recorded arrays only."""
    # Arrays unpickled from out-of-band buffers may be unaligned: the core needs aligned ones.
    def aligned(v: Any) -> Any:
        return np.require(v, np.float64, ["C", "A"]) if isinstance(v, np.ndarray) else v

    reference = aligned(reference)
    options = {k: aligned(v) for k, v in options.items()}
    res = simulate_batch(plants, frictions, controllers, reference, dt, threads=threads, progress=False, **options)
    names = ("position", "velocity", "measured", "command", "friction", "recorded_error")
    return {("error" if k == "recorded_error" else k): getattr(res, k) for k in names if getattr(res, k) is not None}


def _on_executor(
    executor: "Executor",
    chunks: list[tuple[int, int]],
    plants: list[Any],
    frictions: list[Any],
    controllers: list[Any],
    reference: Any,
    dt: float,
    options: Mapping[str, Any],
    threads: int | None,
    report: Callable[[int, int], None] | None,
) -> dict[str, NDArray[np.float64]]:
    """Submit every chunk, then gather the results in run order (stacked like the local run)."""
    if not callable(getattr(executor, "submit", None)):
        raise InvalidInputError(f"`executor` must be a concurrent.futures.Executor (with submit), got {type(executor).__name__}")
    n_runs = len(plants)
    arr = {k: (np.asarray(v) if k in ("feedforward", "input_disturbance", "load_force", "measurement_noise") and np.ndim(v) == 2 else v) for k, v in options.items()}
    ref = np.asarray(reference) if reference is not None and np.ndim(reference) == 2 else reference
    futures = [
        executor.submit(
            _batch_chunk,
            plants[a:b],
            frictions[a:b],
            controllers[a:b],
            _per_run(ref, a, b, n_runs),
            dt,
            {k: _per_run(v, a, b, n_runs) for k, v in arr.items()},
            threads,
        )
        for a, b in chunks
    ]
    parts = []
    for (a, b), fut in zip(chunks, futures):
        try:
            parts.append(fut.result())
        except (InvalidInputError, SimulationError) as exc:
            raise type(exc)(f"runs {a}..{b - 1} (a chunk on the executor): {exc}") from exc
        if report is not None:
            report(b, n_runs)
    return {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}


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
