"""Measured axis data for the identification loop: explicit column mapping, units, checks.

A run is ``time``, ``position`` and the force on the axis, given either directly (``force``) or
as a drive ``command`` times a ``gain`` (a number or the name of a scalar in the file, e.g. EMPS's
``gtau``).  Files are read with :func:`gmsfric.io.read_table`; every problem raises
:class:`~gmsfric.errors.DataError` naming the file, the column and the problem.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import units
from .._validate import float_array, number, positive, show, within_fit_range
from ..errors import DataError
from ..io import Table, load_columns, read_table

#: Fewest samples a run may have: the filter, the derivatives and the held-out split need room.
MIN_SAMPLES = 200

#: Largest share of time steps that may repeat the stamp before them: such samples are merged
#: (averaged), as a logger stamping two samples alike now and then; more is a time column too
#: coarse for the sample rate (a 2 kHz log stamped in whole ms), which is refused.
MAX_REPEATED_STAMPS = 0.01


@dataclass
class AxisData:
    """One measured run of an axis, in SI units.

    Attributes
    ----------
    t : ndarray
        Time (s), strictly increasing, uniformly sampled: a log with irregular steps (timing
        jitter) is resampled onto a uniform grid at its median step when the run is created.
    position : ndarray
        Measured position (m).
    force : ndarray
        Force driving the axis (N): the measured force, or ``gain * command``.
    source : str
        Where the data came from (file name), for messages and reports.
    command, gain : ndarray or None, float or None
        The drive command (input units) and the drive gain (N per unit) when the force was
        given that way; needed to simulate the run in closed loop.
    reference, disturbance : ndarray or None
        Optional reference position (m) and input disturbance (input units, added to the
        controller output: command units, or N when the run gave a force), for the closed-loop
        simulation.
    rotary : bool
        A rotary axis: positions in rad and forces in N m (torques) instead of m and N.
    timing : dict
        The sampling of the time column as read (see :func:`timing_summary`), and whether and
        how the run was resampled; then also ``position_step_as_logged`` (m or rad), the encoder
        step before the interpolation put positions between steps (the position resolution), and
        ``encoder_step_as_logged`` when the log rested on a lattice (see :func:`encoder_step`),
        and ``turns_unwrapped`` when a rotary position wrapped around (kept within one turn by its
        encoder) and was unwrapped.
    observed : ndarray of bool or None
        Set by the resampling: whether each sample of the uniform grid was measured, ``False``
        inside a gap of the log (a step longer than :data:`GAP_STEPS` median steps), where the
        interpolation made it up; ``None`` when every sample was measured.
    """

    t: NDArray[np.float64]
    position: NDArray[np.float64]
    force: NDArray[np.float64]
    source: str = "data"
    command: NDArray[np.float64] | None = None
    gain: float | None = None
    reference: NDArray[np.float64] | None = None
    disturbance: NDArray[np.float64] | None = None
    meta: dict[str, float] = field(default_factory=dict)
    rotary: bool = False
    timing: dict[str, Any] = field(default_factory=dict)
    observed: NDArray[np.bool_] | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.rotary, (bool, np.bool_)):
            raise DataError(f"{self.source}: `rotary` must be True or False, got {show(self.rotary)}")
        if self.gain is not None and not (np.isfinite(number("gain", self.gain)) and self.gain != 0):
            raise DataError(f"{self.source}: `gain` must be finite and non-zero, got {show(self.gain)}")
        n = None
        for name in ("t", "position", "force", "command", "reference", "disturbance"):
            a = getattr(self, name)
            if a is None and name not in ("t", "position", "force"):
                continue
            a = float_array(name, a)
            if a.ndim != 1:
                raise DataError(f"{self.source}: `{name}` must be one-dimensional, got shape {a.shape}")
            setattr(self, name, a)
            n = a.size if n is None else n
            if a.size != n:
                raise DataError(f"{self.source}: {name} has {a.size} samples but time has {n}")
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise DataError(f"{self.source}: {name} has a non-finite value at row {bad[0]}")
        n = self.t.size
        if n < MIN_SAMPLES:
            raise DataError(f"{self.source}: too few samples ({n}); the loop needs at least {MIN_SAMPLES}")
        d = np.diff(self.t)
        if np.any(d < 0):
            i = int(np.flatnonzero(d < 0)[0]) + 1
            raise DataError(f"{self.source}: time is not strictly increasing at row {i} (it goes back)")
        repeated = int(np.count_nonzero(d == 0))
        if repeated > MAX_REPEATED_STAMPS * d.size:
            i = int(np.flatnonzero(d == 0)[0]) + 1
            raise DataError(f"{self.source}: time is not strictly increasing at row {i}: {repeated} of {n} time stamps repeat the one "
                            "before, too many for a late sample now and then; is the time column rounded too coarsely for the "
                            "sample rate?")
        for name in ("t", "position", "force", "command", "reference", "disturbance"):
            if (a := getattr(self, name)) is not None:
                within_fit_range(f"{self.source}: {name}", a, error=DataError)
        turns = self._unwrap_turns() if self.rotary else 0  # before samples are averaged across a wrap
        if repeated:
            self._merge_repeated_stamps()
            d = np.diff(self.t)
            if self.t.size < MIN_SAMPLES:
                raise DataError(f"{self.source}: too few samples ({self.t.size} time stamps); the loop needs at least {MIN_SAMPLES}")
        within_fit_range(f"{self.source}: position", self.position, time_step=float(np.min(d)), error=DataError)
        if not self.timing:
            self.timing = timing_summary(self.t)
            if turns:
                self.timing["turns_unwrapped"] = turns
            if repeated:
                self.timing.update(samples_in=n, repeated_stamps_merged=repeated)
            if self.timing["irregular"]:
                self._resample()
        if np.ptp(self.position) == 0:
            raise DataError(f"{self.source}: position never changes; nothing to identify")
        if not np.any(self.force != 0):
            raise DataError(f"{self.source}: force is zero everywhere")

    def _unwrap_turns(self) -> int:
        """Undo an encoder's wrap-around (an angle kept within one turn): a change of more than
        half a turn between two samples is no motion of a servo axis (pi rad per sample is
        3000 rad/s at 1 kHz), and when each such change is a whole turn give or take
        :data:`WRAP_TOLERANCE`, the turns are added back; any other jump is refused.  Returns
        how many jumps of the position were unwrapped."""
        unwrapped = 0
        for name in ("position", "reference"):
            a = getattr(self, name)
            if a is None:
                continue
            d = np.diff(a)
            jumps = np.flatnonzero(np.abs(d) > np.pi)
            if not jumps.size:
                continue
            turns = d[jumps] / (2.0 * np.pi)
            odd = np.flatnonzero(np.abs(turns - np.round(turns)) > WRAP_TOLERANCE)
            if odd.size:
                i = int(jumps[odd[0]])
                raise DataError(f"{self.source}: {name} jumps by {d[i]:.4g} rad between rows {i} and {i + 1}: more than half a turn in "
                                "one sample, and not a whole turn as an encoder that wraps around makes; a corrupt or mislabelled column?")
            setattr(self, name, np.unwrap(a, period=2.0 * np.pi))
            if name == "position":
                unwrapped = int(jumps.size)
        return unwrapped

    def _merge_repeated_stamps(self) -> None:
        """One sample per time stamp: the samples logged under one stamp averaged."""
        self.t, group, count = np.unique(self.t, return_inverse=True, return_counts=True)
        for name in ("position", "force", "command", "reference", "disturbance"):
            a = getattr(self, name)
            if a is not None:
                setattr(self, name, np.bincount(group, weights=a) / count)

    def _resample(self) -> None:
        """Put every signal on a uniform grid at the median step (linear interpolation).

        Real loggers are late now and then; the filters, derivatives and decimation of the
        recipe need a uniform grid, and a timing error of a fraction of a step is far smaller
        than the dynamics the loop identifies.  The measured jitter stays in ``timing``.  Across a
        gap (samples lost) the straight line is no measurement: the grid's samples inside one are
        marked unobserved (:attr:`observed`), and the loop leaves them out."""
        step = self.timing["median_step_s"]
        # interpolation puts positions between the encoder's steps: keep the step as logged
        self.timing["position_step_as_logged"] = quantisation_step(self.position)
        if (lattice := encoder_step(self.position)) is not None:
            self.timing["encoder_step_as_logged"] = lattice
        span = (self.t[-1] - self.t[0]) / step
        if not span < MAX_GRID_PER_SAMPLE * self.t.size:  # checked before the grid is allocated
            i = int(np.argmax(np.diff(self.t)))
            raise DataError(f"{self.source}: the log spans {self.t[-1] - self.t[0]:.4g} s, {span:.3g} steps of its median "
                            f"{step:.3g} s for {self.t.size} samples: mostly gaps (the longest after row {i}, "
                            f"{self.t[i + 1] - self.t[i]:.4g} s); cut the log into the runs it holds")
        n = int(np.floor(span + 1e-9)) + 1
        tu = self.t[0] + step * np.arange(n)
        gaps = np.flatnonzero(np.diff(self.t) > GAP_STEPS * step)
        if gaps.size:
            eps = 1e-6 * step  # a grid sample on a measured one (to rounding) is measured
            edges = np.zeros(n + 1, dtype=np.int64)
            np.add.at(edges, np.searchsorted(tu, self.t[gaps] + eps, side="right"), 1)
            np.add.at(edges, np.searchsorted(tu, self.t[gaps + 1] - eps, side="left"), -1)
            observed = np.cumsum(edges[:n]) == 0
            self.observed = observed
            self.timing["samples_in_gaps"] = int(n - observed.sum())
        for name in ("position", "force", "command", "reference", "disturbance"):
            a = getattr(self, name)
            if a is not None:
                setattr(self, name, np.interp(tu, self.t, a))
        self.t = tu
        self.timing.update(resampled=True, samples_out=int(n),
                           method="linear interpolation of every column onto a uniform grid at the median step")

    @property
    def dt(self) -> float:
        """Median sample step (s)."""
        return float(np.median(np.diff(self.t)))

    def __len__(self) -> int:
        return int(self.t.size)


def on_the_same_turn(est: AxisData, val: AxisData) -> AxisData:
    """``val`` moved by whole turns onto the travel of ``est`` when either run's rotary encoder
    wrapped around (unwrapped, each run keeps the turn of its first sample, and which turn that
    is the log does not say); ``val`` itself when neither wrapped or it already lies there.  A
    copy is moved, never ``val``."""
    if not (est.rotary and (est.timing.get("turns_unwrapped") or val.timing.get("turns_unwrapped"))):
        return val
    k = int(np.round((np.median(est.position) - np.median(val.position)) / (2.0 * np.pi)))
    if k == 0:
        return val
    moved = copy.copy(val)
    moved.position = val.position + 2.0 * np.pi * k
    if val.reference is not None:
        moved.reference = val.reference + 2.0 * np.pi * k
    moved.timing = {**val.timing, "turns_moved_onto_estimation_travel": k}
    return moved


def quantisation_step(position: NDArray[np.float64]) -> float:
    """Smallest position change a quantised log resolves (its encoder step): the 1st percentile of
    the non-zero sample-to-sample changes; 0 when the position never changes."""
    d = np.abs(np.diff(position))
    span = float(np.ptp(position)) or 1.0
    nz = d[d > 1e-12 * span]
    return float(np.percentile(nz, 1)) if nz.size else 0.0


#: A lattice is the encoder's when the position stays put between at least this share of samples...
LATTICE_REST_SHARE = 1e-3
#: ...and at least this many changes are a single step.
LATTICE_MIN_SINGLE_STEPS = 10


def encoder_step(position: NDArray[np.float64]) -> float | None:
    """The encoder's step, read off the lattice the log rests on; None when the log shows none.

    The 1st percentile of the changes (:func:`quantisation_step`) overstates the step of a fast
    log of fast moves, which changes by one step only next to reversals.  The smallest change is
    the step when at least 99 % of the changes below ten of it are whole multiples of it (within
    10 %, for logs written with few digits), the position stays put between at least
    :data:`LATTICE_REST_SHARE` of the samples and :data:`LATTICE_MIN_SINGLE_STEPS` changes are one
    step.  A log stored more finely than its sensor resolves sits on the lattice of its storage
    and almost never stands still (the real EMPS runs change by multiples of 0.05 um and stand
    still between 1 of 25 000 samples): its lattice says nothing about the sensor."""
    d = np.abs(np.diff(position))
    span = float(np.ptp(position)) or 1.0
    at_rest = d <= 1e-12 * span
    nz = d[~at_rest]
    if nz.size == 0 or at_rest.mean() < LATTICE_REST_SHARE:
        return None
    step = float(nz.min())
    r = nz[nz < 10.0 * step] / step
    on_lattice = np.abs(r - np.round(r)) <= 0.1
    if on_lattice.mean() < 0.99 or np.count_nonzero(np.abs(r - 1.0) <= 0.1) < LATTICE_MIN_SINGLE_STEPS:
        return None
    return step


#: Relative spread of the time steps above which a log counts as irregular and is resampled.
JITTER_TOLERANCE = 0.01

#: Share of a turn by which a jump of a rotary position may differ from whole turns and still be
#: an encoder's wrap-around: the axis's own motion within the sample.
WRAP_TOLERANCE = 0.05

#: Samples of the uniform grid per logged sample beyond which a log is mostly gaps and refused
#: (the grid would be made up rather than measured, and could not be allocated).
MAX_GRID_PER_SAMPLE = 10.0

#: A time step longer than this many median steps is a gap in the log (samples lost), not a late
#: sample: loggers that jitter stay within about twice their step (a 100 Hz robot log: 2 to 12 ms).
GAP_STEPS = 4.0


def timing_summary(t: NDArray[np.float64]) -> dict[str, Any]:
    """The sampling of a time column: median, smallest and largest step, the share of steps that
    differ from the median by more than :data:`JITTER_TOLERANCE`, and whether that makes the log
    irregular (then :class:`AxisData` resamples it); the gaps (steps longer than :data:`GAP_STEPS`
    median steps) and the longest of them."""
    d = np.diff(t)
    med = float(np.median(d))
    off = np.abs(d - med) > JITTER_TOLERANCE * med
    gaps = d > GAP_STEPS * med
    return {
        "irregular": bool(off.any()),
        "resampled": False,
        "median_step_s": med,
        "min_step_s": float(d.min()),
        "max_step_s": float(d.max()),
        "step_std_s": float(d.std()),
        "irregular_steps_pct": float(100.0 * off.mean()),
        "gaps": int(gaps.sum()),
        "longest_gap_s": float(d[gaps].max()) if gaps.any() else 0.0,
        "samples_in": int(t.size),
    }


def load_axis_data(
    path: str | Path | Table,
    *,
    time: str | None = None,
    position: str,
    force: str | None = None,
    command: str | None = None,
    gain: str | float | None = None,
    reference: str | None = None,
    disturbance: str | None = None,
    time_unit: str = "s",
    position_unit: str = "m",
    force_unit: str = "N",
    sample_rate: float | None = None,
) -> AxisData:
    """Read one run from a CSV (header row) or MATLAB .mat file with explicit column names.

    Parameters
    ----------
    path : str, Path or Table
        The file (or an already read :class:`gmsfric.io.Table`).
    time, position : str
        Column names of time and measured position.  A log without a time column gives
        ``sample_rate`` instead of ``time``.
    force : str, optional
        Column of the force on the axis.  Give either ``force`` or ``command`` and ``gain``.
    command : str, optional
        Column of the drive command (e.g. volts).
    gain : str or float, optional
        Drive gain, force per command unit (N/unit): a number or the name of a scalar in the file.
    reference, disturbance : str, optional
        Columns of the reference position (same unit as ``position``) and of an input
        disturbance added to the controller output (command units with ``command``; with
        ``force`` the drive is the force, so ``force_unit``), used only for the closed-loop
        simulation.
    sample_rate : float, optional
        Samples per second (Hz) of a log without a time column: its time runs from 0 in steps of
        ``1 / sample_rate``.  Give either ``time`` or ``sample_rate``.
    time_unit, position_unit, force_unit : str
        Units in the file, any that :mod:`gmsfric.units` reads (``s``, ``ms``; ``m``, ``mm``,
        ``um``; ``N``, ``mN``, ``kN``).  A rotary axis gives its position in ``rad`` or ``deg`` and
        its force as a torque (``N m``).

    Returns
    -------
    AxisData

    Raises
    ------
    DataError
        Unknown column or scalar, mismatched lengths, non-finite values, non-monotonic time,
        too few samples, or an ambiguous force specification.  Irregular time steps are not an
        error: the run is resampled (see :class:`AxisData`).
    UnitError
        A unit that is unknown or not of its quantity (checked before the file is read).
    """
    kt = units.factor(time_unit, "time", name="time_unit")
    rotary = units.is_rotary(position_unit, "position", name="position_unit")
    kq = units.factor(position_unit, "position", name="position_unit")
    kf = units.factor(force_unit, "force", rotary=rotary, name="force_unit")
    if (time is None) == (sample_rate is None):
        raise DataError("give either a time column (`time`) or a sample rate (`sample_rate`), not both, not neither")
    fs = None if sample_rate is None else positive("sample_rate", number("sample_rate", sample_rate))
    table = path if isinstance(path, Table) else read_table(path)
    if (force is None) == (command is None):
        raise DataError(f"{table.source}: give either a force column or a command column with a gain (not both, not neither)")
    if command is not None and gain is None:
        raise DataError(f"{table.source}: a command column needs a drive gain (a number or a scalar name in the file)")
    if force is not None and gain is not None:
        raise DataError(f"{table.source}: a gain only makes sense with a command column")
    mapping = {"position": position} if time is None else {"time": time, "position": position}
    if force is not None:
        mapping["force"] = force
    else:
        mapping["command"] = command  # type: ignore[assignment]
    if reference is not None:
        mapping["reference"] = reference
    if disturbance is not None:
        mapping["disturbance"] = disturbance
    declared = {"time": (time_unit, "time", "time_unit"), "position": (position_unit, "position", "position_unit"),
                "reference": (position_unit, "position", "position_unit")}
    if force is not None:
        declared.update(force=(force_unit, "force", "force_unit"), disturbance=(force_unit, "force", "force_unit"))
    cols = load_columns(table, mapping, min_samples=MIN_SAMPLES, repeated_time=True, declared_units=declared)
    g = None
    if command is not None:
        g = table.number(gain, role="gain")  # type: ignore[arg-type]
        if g == 0:
            raise DataError(f"{table.source}: drive gain {gain!r} is zero")
        f = g * cols["command"]
    else:
        f = cols["force"] * kf
    return AxisData(
        t=cols["time"] * kt if fs is None else np.arange(cols["position"].size) / fs,
        position=cols["position"] * kq,
        force=f,
        source=Path(table.source).name,
        command=cols.get("command"),
        gain=g,
        reference=None if reference is None else cols["reference"] * kq,
        # with a force column the drive is the force: its disturbance is a force too, in SI
        disturbance=None if disturbance is None else cols["disturbance"] * (1.0 if command is not None else kf),
        meta=dict(table.scalars),
        rotary=rotary,
    )
