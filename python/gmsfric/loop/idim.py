"""Inverse-model least squares (IDIM-LS): the EMPS recipe and the regression machinery.

Recipe (Janot, Gautier & Brunot 2019): zero-phase Butterworth low-pass on the position (order 4,
100 Hz at 1 kHz), central differences for velocity and acceleration, edge samples dropped, and
every column (force included) decimated with a zero-phase anti-aliasing filter ("parallel
decimation").  The force is then linear in the parameters::

    f = M qdd + Fv qd + Fc sign(qd) + offset + sum_k theta_k phi_k(q, qd, qdd, t)

Extra columns ``phi_k`` come from the effect catalogue (:mod:`gmsfric.loop.effects`); effects
with a nonlinear parameter (a Stribeck velocity, a delay, a resonance) are fitted by a grid over
that parameter with the linear ones solved exactly at each grid point.
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Callable, Collection, Sequence, TypeGuard

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage, signal

from .._validate import count, finite
from ..errors import IdentificationError, InvalidInputError
from .data import AxisData, encoder_step, quantisation_step

Array = NDArray[np.float64]


#: The recipe's largest position filter cut-off (Hz).
RECIPE_CUTOFF_HZ = 100.0

#: Position filter cut-offs tried when none is given, as fractions of the sample rate, none above
#: :data:`RECIPE_CUTOFF_HZ`.  The recipe's ``fs / 10`` suits 1 kHz logs, whose columns and force
#: are then band-limited alike by the decimation filter (40 Hz).  Logged slower there is little or
#: no decimation, the force keeps its band up to Nyquist, and a position filtered at ``fs / 10``
#: lags it in the fast parts of the motion (the stick at reversals): on 100 Hz robot logs the true
#: model's held-out error was 10.8 % at 10 Hz and 0.75 % at 20 Hz, and a 12 ms "delay" fitted
#: the difference.
CUTOFF_FRACTIONS = (0.1, 0.2, 0.3)


@dataclass(frozen=True)
class Preprocessing:
    """Filtering and decimation of the EMPS recipe, scaled to the sample rate.

    Parameters
    ----------
    cutoff_hz : float, optional
        Butterworth cut-off (Hz); default ``min(100, fs/10)``, and below 1 kHz the loop chooses
        among :meth:`cutoffs` on the estimation run.
    order : int
        Butterworth order (applied forward and backward).
    decimation : int, optional
        Decimation factor; default ``max(1, round(fs / 100))`` (the recipe's 100 Hz rows).
    edge_s : float
        Time dropped at both ends (s) before decimating (the recipe drops 49 samples at 1 kHz).
    """

    cutoff_hz: float | None = None
    order: int = 4
    decimation: int | None = None
    edge_s: float = 0.049

    def __post_init__(self) -> None:
        if self.cutoff_hz is not None and not finite("cutoff_hz", self.cutoff_hz) > 0:
            raise InvalidInputError(f"`cutoff_hz` must be positive, got {self.cutoff_hz}")
        count("order", self.order, minimum=1, maximum=12)
        if self.decimation is not None:
            count("decimation", self.decimation, minimum=1)
        if not finite("edge_s", self.edge_s) >= 0:
            raise InvalidInputError(f"`edge_s` must be >= 0, got {self.edge_s}")

    def resolve(self, fs: float) -> tuple[float, int, int]:
        if not finite("fs", fs) > 0:
            raise InvalidInputError(f"`fs` must be positive, got {fs}")
        fc = self.cutoff_hz if self.cutoff_hz is not None else min(RECIPE_CUTOFF_HZ, fs / 10.0)
        fc = min(fc, 0.45 * fs)
        dec = self.decimation if self.decimation is not None else max(1, int(round(fs / 100.0)))
        edge = int(round(self.edge_s * fs))
        return float(fc), int(dec), edge

    def cutoffs(self, fs: float) -> list[float]:
        """Position filter cut-offs to choose from at sample rate ``fs``: the given one, or the
        recipe's followed by the distinct :data:`CUTOFF_FRACTIONS` of ``fs`` up to
        :data:`RECIPE_CUTOFF_HZ` (only the recipe's at 1 kHz and above)."""
        out = [self.resolve(fs)[0]]
        if self.cutoff_hz is None:
            for c in sorted(min(RECIPE_CUTOFF_HZ, f * fs) for f in CUTOFF_FRACTIONS):
                if c > 1.05 * out[-1]:  # distinct cut-offs only (a 999.9 Hz clock is a 1 kHz log)
                    out.append(c)
        return out


#: Rows slower than this fraction of the run's speed scale (99th percentile of |qd|) are at rest.
REST_FRACTION = 0.01


def position_noise(raw: Array, filtered: Array) -> float:
    """Noise of the measured position: the robust spread of raw minus filtered position."""
    hf = raw - filtered
    return float(1.4826 * np.median(np.abs(hf - np.median(hf))))


def _a_length_within(step: object, span: float) -> TypeGuard[float]:
    """Whether a step taken from ``timing`` (which can be hand-made) is a positive length within
    the travel ``span``."""
    return isinstance(step, (int, float)) and bool(np.isfinite(step)) and 0.0 < step <= span


def position_resolution(raw: Array, filtered: Array, logged_step: float | None = None) -> float:
    """Smallest position change the data resolve: the encoder step of a quantised position (the
    smallest non-zero sample-to-sample change; ``logged_step``, that step measured before a
    resampling, when the run was resampled) or, when the position is noisy rather than quantised,
    the noise level (robust spread of raw minus filtered position)."""
    span = float(np.ptp(raw)) or 1.0
    step = float(logged_step) if _a_length_within(logged_step, span) else quantisation_step(raw)
    return max(step, position_noise(raw, filtered), 1e-12 * span)


def contact_resolution(raw: Array, filtered: Array, resolution: float, lattice: float | None) -> float:
    """Narrowest elastic range a contact driven by the measured position can show: the encoder
    step ``lattice`` when the log rests on its lattice (:func:`~gmsfric.loop.data.encoder_step`,
    measured before any resampling), not below the position noise; ``resolution`` otherwise.

    Pre-sliding blocks follow the raw position, so a block a few steps wide is seen wherever the
    encoder resolves it, even on a fast log whose 1st percentile of changes (``resolution``,
    which sets what counts as standstill) is many steps."""
    span = float(np.ptp(raw)) or 1.0
    if not _a_length_within(lattice, span):
        return resolution
    return min(resolution, max(float(lattice), position_noise(raw, filtered), 1e-12 * span))


@functools.lru_cache(maxsize=None)
def _antialias_sos(dec: int) -> Array:
    """The anti-aliasing filter of :func:`scipy.signal.decimate` by ``dec`` (its default: order-8
    Chebyshev type I, 0.05 dB ripple, cut-off at 0.8 of the new Nyquist frequency)."""
    return signal.cheby1(8, 0.05, 0.8 / dec, output="sos")


def zero_phase_decimate(x: Array, dec: int) -> Array:
    """:func:`scipy.signal.decimate` by ``dec`` along the first axis (zero-phase, its default
    filter), with the filter designed once per factor: the loop decimates hundreds of regression
    columns per run, and designing the filter cost as much as filtering a column."""
    return signal.sosfiltfilt(_antialias_sos(dec), x, axis=0)[::dec]


@functools.lru_cache(maxsize=None)
def decimation_gain(dec: int) -> float:
    """Gain at zero frequency of :func:`scipy.signal.decimate` (zero-phase, default filter).

    Its Chebyshev filter has even order, so its ripple band starts below 1 at zero frequency
    (0.9943, squared by the zero-phase pass): a decimated ramp comes out 1.15 % short.  The
    regression is immune (force and columns shrink alike), but decimated positions and times
    taken as values (residual profiles along the travel, periods, time stamps) are not."""
    # a constant passes the zero-phase pass (started in steady state) as gain x constant
    return float(np.mean(zero_phase_decimate(np.ones(64), dec)))


#: Fraction of a step that the decimation filter may still leave beside it at a settled row.
DECIMATION_SETTLING_TOL = 0.01


#: Bytes of regression columns one run keeps (per :class:`Signals`): the loop builds a column
#: for every grid point of every effect, at the full sample rate, and a long log at a high rate
#: (half a million samples) filled 5.6 GB with them; beyond this the least recently used are made
#: again when needed.
CACHE_BYTES = 768 * 2**20

#: Periods of the velocity filter's cut-off over which samples next to a gap in the log are left
#: out: the zero-phase filter spreads what the interpolation made up over them.
GAP_SETTLING_PERIODS = 2.0


def gap_reach(fs: float, cutoff: float) -> int:
    """Samples on either side of a gap whose filtered states the gap reaches."""
    return max(1, int(np.ceil(GAP_SETTLING_PERIODS * fs / cutoff)))


def near_a_gap(observed: Array | None, n: int, reach: int) -> Array:
    """The samples of a run of ``n`` within ``reach`` samples of an unobserved one (none when
    ``observed`` is ``None``)."""
    if observed is None or observed.all():
        return np.zeros(n, dtype=bool)
    return ndimage.maximum_filter1d((~observed).astype(np.uint8), 2 * reach + 1).astype(bool)


@functools.lru_cache(maxsize=None)
def decimation_settling_rows(dec: int) -> int:
    """Rows on either side of a step over which :func:`scipy.signal.decimate` (zero-phase, the
    recipe's order-8 Chebyshev) leaves more than ``DECIMATION_SETTLING_TOL`` of the step: about 7
    for every factor above 1 (70 ms at the recipe's 100 Hz rows), 0 without decimation.

    A force step the regressors do not share (the force crossing the stiction band while the axis
    holds) rings over that many rows, longer than the velocity filter's own settling."""
    if dec <= 1:
        return 0
    # the filter scales with the factor, so its ringing in rows barely depends on it; a capped
    # factor keeps the probe small for very large ones
    dec = min(dec, 50)
    n = 64
    x = np.r_[np.zeros(n * dec), np.ones(n * dec)]
    y = zero_phase_decimate(x, dec) / decimation_gain(dec)
    k = np.arange(y.size)
    off = np.abs(y - (k >= n)) > DECIMATION_SETTLING_TOL
    near = np.abs(k - n) < n // 2  # clear of the ends' padding
    return int(np.max(np.abs(k[off & near] - n), initial=0))


class Signals:
    """One run after preprocessing: full-rate filtered states and decimated regression rows.

    Attributes
    ----------
    data : AxisData
    q, qd, qdd : ndarray
        Filtered position (m), velocity (m/s), acceleration (m/s^2) at the full rate.
    y : ndarray
        Decimated force rows (N): the regression target.
    rows : dict[str, ndarray]
        Decimated ``t``, ``q``, ``qd``, ``qdd`` aligned with ``y`` (for residual analysis).
    moving : ndarray of bool
        Rows where the axis moves (``|qd| >= rest_speed``); the others are standstill.
    resolution : float
        Position resolution (see :func:`position_resolution`).
    contact_resolution : float
        Narrowest pre-sliding block the position shows (see :func:`contact_resolution`).
    """

    def __init__(self, data: AxisData, pre: Preprocessing = Preprocessing(), *, q_range: tuple[float, float] | None = None, t0: float | None = None,
                 rest_speed: float | None = None) -> None:
        self.data, self.pre = data, pre
        self.dt = data.dt
        self.fs = 1.0 / self.dt
        self.cutoff, self.dec, self.edge = pre.resolve(self.fs)
        duration = float(data.t[-1] - data.t[0])
        if self.cutoff * duration < 10.0:
            # the filter's and the stuck test's windows span a period of the cut-off
            raise InvalidInputError(f"`cutoff_hz` = {self.cutoff:.3g} Hz leaves fewer than 10 of its periods in {data.source} ({duration:.3g} s)")
        n = len(data)
        if n - 2 * self.edge < 20 * self.dec:
            raise IdentificationError(f"{data.source}: {n} samples leave too few rows after dropping {self.edge} edge samples and decimating by {self.dec}")
        b, a = signal.butter(pre.order, self.cutoff / (self.fs / 2.0))
        q = signal.filtfilt(b, a, data.position)
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        qd[1:-1] = (q[2:] - q[:-2]) / (2 * self.dt)
        qdd[1:-1] = (q[2:] - 2 * q[1:-1] + q[:-2]) / self.dt**2
        qd[0], qd[-1], qdd[0], qdd[-1] = qd[1], qd[-2], qdd[1], qdd[-2]
        self.q, self.qd, self.qdd = q, qd, qdd
        self.t = data.t - data.t[0]
        self.t0 = 0.0 if t0 is None else t0
        #: Position range the position bases are defined on (the estimation run's, for validation).
        self.q_range = q_range if q_range is not None else (float(q.min()), float(q.max()))
        #: Scale of the velocity (robust max) used to place velocity grids.
        self.v_scale = float(np.percentile(np.abs(qd), 99)) or 1.0
        self.duration = float(self.t[-1])
        self.y = self.decimate(data.force)
        self.rows = {"t": self.decimate(self.t), "q": self.decimate(q), "qd": self.decimate(qd), "qdd": self.decimate(qdd)}
        #: Position resolution (m or rad): the encoder step, or the noise of the raw position.
        self.resolution = position_resolution(data.position, q, data.timing.get("position_step_as_logged"))
        #: Narrowest pre-sliding block the position shows (m or rad): the encoder step.
        lattice = data.timing.get("encoder_step_as_logged") if data.timing.get("resampled") else encoder_step(data.position)
        self.contact_resolution = contact_resolution(data.position, q, self.resolution, lattice)
        #: Speed below which a row is at rest (the estimation run's threshold for a validation run).
        self.rest_speed = float(rest_speed) if rest_speed is not None else REST_FRACTION * self.v_scale
        # A sample is stuck when the measured position does not change by more than its
        # resolution within one period of the velocity filter: the velocity is then zero as far
        # as the data can tell, even where the filtered velocity rings (after a stop, at a
        # reversal where the axis sticks while the force crosses the stiction band).
        # The filtered velocity averages over about the same window, so the samples within it
        # of a stop (before the axis starts, after it stops) have a velocity that blends motion
        # and rest: they count as standstill too.
        h = max(1, int(round(self.fs / (2.0 * self.cutoff))))
        span = ndimage.maximum_filter1d(data.position, 2 * h + 1) - ndimage.minimum_filter1d(data.position, 2 * h + 1)
        stuck = ndimage.maximum_filter1d((span <= 1.5 * self.resolution).astype(np.uint8), 2 * h + 1).astype(bool)
        self.stuck = self._rows_of(stuck)
        # Samples a resampling made up across a gap in the log, and those the filters spread
        # them over (see :func:`gap_reach`); the rows widened by the decimation filter's settling.
        near = near_a_gap(data.observed, n, gap_reach(self.fs, self.cutoff))
        #: Full-rate samples clear of gaps in the log.
        self.observed = ~near
        #: Rows in or next to a gap in the log: left out like standstill.
        self.in_gap = self._rows_of(near)
        if self.in_gap.any() and (settle := decimation_settling_rows(self.dec)):
            self.in_gap = ndimage.maximum_filter1d(self.in_gap.astype(np.uint8), 2 * settle + 1).astype(bool)
        #: Rows where the axis moves; at rest a stuck axis holds any force up to break-away
        #: (set-valued stiction), which no regression column describes.
        self.moving = self.moving_above(self.rest_speed)
        self._cache: OrderedDict[tuple, Array] = OrderedDict()
        self._cache_bytes = 0

    def _rows_of(self, mask: Array) -> Array:
        """A full-rate boolean mask at the decimated rows (edges dropped, every ``dec``-th sample)."""
        return np.ascontiguousarray(mask[self.edge : mask.size - self.edge : self.dec][: self.n_rows])

    def moving_above(self, speed: float) -> Array:
        """Rows faster than ``speed`` (filtered velocity) where the measured position moves and the
        log has data."""
        return (np.abs(self.rows["qd"]) >= speed) & ~self.stuck & ~self.in_gap

    def decimate(self, x: Array) -> Array:
        """Drop the edges and decimate (zero-phase), along the first axis."""
        x = np.asarray(x, dtype=float)
        x = x[self.edge : x.shape[0] - self.edge] if self.edge else x
        if self.dec == 1:
            return np.ascontiguousarray(x)
        return np.ascontiguousarray(zero_phase_decimate(x, self.dec) / decimation_gain(self.dec))

    @property
    def n_rows(self) -> int:
        return int(self.y.size)

    def cached(self, key: tuple, make: Callable[[], Array]) -> Array:
        """The array ``make()`` returns, kept under ``key`` while the run's cache holds at most
        :data:`CACHE_BYTES` (the least recently used arrays go first, and are made again when
        asked for)."""
        if key in self._cache:
            self._cache.move_to_end(key)
            return self._cache[key]
        value = make()
        self._cache[key] = value
        self._cache_bytes += value.nbytes
        while self._cache_bytes > CACHE_BYTES and len(self._cache) > 1:
            self._cache_bytes -= self._cache.popitem(last=False)[1].nbytes
        return value


# ------------------------------------------------------------------------------------------
# Terms: a term turns a run into full-rate regression columns for given hyper-parameters.


@dataclass(frozen=True)
class Term:
    """A group of regression columns ``phi(sig, hyper) -> (n, k)`` with parameter names."""

    name: str
    param_names: tuple[str, ...]
    build: Callable[[Signals, tuple], Array]
    hyper: tuple = ()
    hyper_names: tuple[str, ...] = ()

    def full(self, sig: Signals) -> Array:
        return sig.cached(("full", self.name, self.param_names, self.hyper), lambda: np.atleast_2d(np.asarray(self.build(sig, self.hyper), dtype=float).T).T.reshape(sig.q.size, -1))

    def with_hyper(self, hyper: tuple) -> "Term":
        return Term(self.name, self.param_names, self.build, tuple(hyper), self.hyper_names)


def advance(x: Array, steps: float) -> Array:
    """``x(t + steps*dt)`` by linear interpolation (edges held)."""
    if steps == 0:
        return x
    n = x.shape[0]
    idx = np.clip(np.arange(n) + steps, 0, n - 1)
    i0 = np.floor(idx).astype(int)
    i1 = np.minimum(i0 + 1, n - 1)
    w = (idx - i0)[:, None]
    return x[i0] * (1 - w) + x[i1] * w


def term_rows(term: Term, sig: Signals, delay_steps: float = 0.0) -> Array:
    """Decimated regression rows of ``term`` on ``sig``, with the force delayed ``delay_steps`` samples."""
    key = ("rows", term.name, term.param_names, term.hyper, round(delay_steps, 4))

    def make() -> Array:
        return sig.decimate(advance(term.full(sig), delay_steps))

    return sig.cached(key, make)


BASE_TERMS: dict[str, Term] = {
    "inertia": Term("inertia", ("M",), lambda s, h: s.qdd),
    "viscous": Term("viscous", ("Fv",), lambda s, h: s.qd),
    "coulomb": Term("coulomb", ("Fc",), lambda s, h: np.sign(s.qd)),
    "offset": Term("offset", ("offset",), lambda s, h: np.ones_like(s.q)),
}

#: The EMPS reference model: ``f = M qdd + Fv qd + Fc sign(qd) + offset``.
REFERENCE_MODEL = ("inertia", "viscous", "coulomb", "offset")


@dataclass
class LinearModel:
    """A force model linear in its parameters: terms, an input delay, fitted parameters.

    Attributes
    ----------
    terms : list of Term
    delay : float
        Input delay (s): the force acts ``delay`` after it is commanded.
    theta, cov : ndarray
        Parameters and their covariance (least squares, residual variance scaled).
    effects : list of str
        Catalogue effects the model contains, in the order they were added.
    """

    terms: list[Term]
    delay: float = 0.0
    theta: Array | None = None
    cov: Array | None = None
    effects: list[str] = field(default_factory=list)
    extras: dict[str, float] = field(default_factory=dict)

    @property
    def param_names(self) -> list[str]:
        return [p for t in self.terms for p in t.param_names]

    @property
    def n_params(self) -> int:
        return len(self.param_names) + (1 if self.delay else 0) + sum(len(t.hyper) for t in self.terms)

    def X(self, sig: Signals) -> Array:
        steps = self.delay / sig.dt
        return np.hstack([term_rows(t, sig, steps) for t in self.terms])

    def fit(self, sig: Signals, rows: NDArray[np.bool_] | slice | None = None) -> "LinearModel":
        """Least squares on ``sig`` (optionally on a subset of rows); returns self."""
        X, y = self.X(sig), sig.y
        if rows is not None:
            X, y = X[rows], y[rows]
        theta, cov = lstsq(X, y)
        self.theta, self.cov = theta, cov
        return self

    def predict(self, sig: Signals) -> Array:
        if self.theta is None:
            raise IdentificationError("model is not fitted")
        return self.X(sig) @ self.theta

    def term_force(self, sig: Signals, names: Collection[str]) -> Array:
        """The fitted force of the terms whose names are in ``names``, on the decimated rows of
        ``sig`` (zero when the model has none of them)."""
        if self.theta is None:
            raise IdentificationError("model is not fitted")
        if isinstance(names, str):  # one name, not its characters
            names = (names,)
        steps = self.delay / sig.dt
        force = np.zeros(sig.n_rows)
        k = 0
        for t in self.terms:
            n = len(t.param_names)
            if t.name in names:
                force += term_rows(t, sig, steps) @ self.theta[k:k + n]
            k += n
        return force

    def params(self) -> dict[str, dict[str, float]]:
        """``{name: {"value", "std"}}`` including hyper-parameters (std NaN: grid-selected)."""
        out: dict[str, dict[str, float]] = {}
        if self.theta is not None:
            std = np.sqrt(np.clip(np.diag(self.cov), 0, None)) if self.cov is not None else np.full(self.theta.size, np.nan)
            for name, v, s in zip(self.param_names, self.theta, std):
                out[name] = {"value": float(v), "std": float(s)}
        for t in self.terms:
            for hn, hv in zip(t.hyper_names, t.hyper):
                out[hn] = {"value": float(hv), "std": float("nan")}
        if self.delay:
            out["delay_s"] = {"value": float(self.delay), "std": float("nan")}
        for k, v in self.extras.items():
            out[k] = {"value": float(v), "std": float("nan")}
        return out

    def copy(self) -> "LinearModel":
        return LinearModel(list(self.terms), self.delay, None, None, list(self.effects), dict(self.extras))

    def describe(self) -> str:
        parts = {"inertia": "M qdd", "viscous": "Fv qd", "coulomb": "Fc sign(qd)", "offset": "offset"}
        body = " + ".join(parts.get(t.name, t.name) for t in self.terms)
        if self.delay:
            if "input_delay" in self.effects:
                body += f", force delayed {self.delay * 1e3:.3g} ms"
            else:
                body += f", force aligned {self.delay * 1e3:.3g} ms later (sampling hold and timing within one sample)"
        return "f = " + body


def lstsq(X: Array, y: Array) -> tuple[Array, Array]:
    """Least squares with column scaling; returns ``theta`` and its covariance."""
    if X.shape[0] <= X.shape[1]:
        raise IdentificationError(f"{X.shape[0]} rows for {X.shape[1]} parameters: not enough data")
    scale = np.sqrt((X**2).sum(axis=0))
    scale[scale == 0] = 1.0
    Xs = X / scale
    G = Xs.T @ Xs
    try:
        L = np.linalg.cholesky(G)
        theta_s = np.linalg.solve(L.T, np.linalg.solve(L, Xs.T @ y))
        if not np.all(np.isfinite(theta_s)) or np.min(np.diag(L)) ** 2 < 1e-12 * np.max(np.diag(G)):
            raise np.linalg.LinAlgError
        Linv = np.linalg.inv(L)
        cov_unit = Linv.T @ Linv
    except np.linalg.LinAlgError:
        theta_s, *_ = np.linalg.lstsq(Xs, y, rcond=None)
        cov_unit = np.linalg.pinv(G)
    r = y - Xs @ theta_s
    sigma2 = float(r @ r) / (X.shape[0] - X.shape[1])
    cov_s = sigma2 * cov_unit
    theta = theta_s / scale
    cov = cov_s / np.outer(scale, scale)
    return theta, cov


def relative_error(y: Array, y_hat: Array) -> float:
    """``100 ||y - y_hat|| / ||y||`` (percent)."""
    return float(100.0 * np.linalg.norm(y - y_hat) / np.linalg.norm(y))


def reference_model() -> LinearModel:
    """The EMPS reference structure (unfitted)."""
    return LinearModel([BASE_TERMS[n] for n in REFERENCE_MODEL])


def fit_baseline(est: Signals, terms: Sequence[str] = REFERENCE_MODEL) -> LinearModel:
    """IDIM-LS fit of the baseline structure on a whole run."""
    return LinearModel([BASE_TERMS[n] for n in terms]).fit(est)
