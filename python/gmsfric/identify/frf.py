"""Frequency response from band-limited random excitation, and the plant fit of paper eq. 1.

``H1 = S_uy / S_uu`` (scipy.signal.csd / welch, Hann windows, 50 % overlap) with the coherence
``gamma^2``.  With feedback, pass the external ``excitation`` r: ``H = S_ry / S_ru`` (the
joint input-output estimate), unbiased by measurement noise fed back through the controller.

:func:`fit_plant` fits ``a / (s^2 + b s + c) exp(-s delay)`` by frequency-domain nonlinear least
squares.  Each bin's complex error is divided by the standard deviation of the H1 estimate,
``|H| sqrt((1 - gamma^2) / (2 n_avg gamma^2))`` (Bendat & Piersol), so coherence weights the
fit and the residuals are ~unit variance.  Start values need not be given: a linear
(Levy) least-squares fit of ``H (s^2 + b s + c) = a exp(-s tau)`` is solved on a grid of delays,
and the exact sampled model's linear fit for every whole number of delay samples the spacing of
the excited lines can resolve (a periodic multisine's lines, else the bins); the best of each
start the nonlinear fit.  The bins' noise always comes from the measurement (never from the
fitted model's residual), so chi2 shows a misfit; with a periodic excitation it includes the
bias a quantized output's repeating quantization error leaves.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import least_squares

from .. import units as _units
from .._validate import measured_signal, positive, same_length, step
from ..errors import IdentificationError, InvalidInputError, SimulationError
from ..batch import simulate_batch
from ..system import Plant
from .diagnostics import Findings, check_bounds, check_chi2, check_feedback, check_saturation, check_stderr, emit
from .results import IdentificationResult, covariance_from_jacobian, transform_covariance
from .sampling import quantum

PLANT_NAMES = ("a", "b", "c", "delay")
COHERENCE_CAP = 0.9995

#: Quantity of each plant parameter (for :mod:`gmsfric.units`).
PLANT_QUANTITIES = {"a": "plant_gain", "b": "rate", "c": "rate_squared", "delay": "time", "force_gain": "force_gain"}


def plant_units(time_unit: str = "s", input_unit: str = "V", output_unit: str = "m", force_gain_unit: str | None = None) -> tuple[dict[str, str], str]:
    """Units of ``a b c delay`` (and ``force_gain``) for data in the given units, after checking
    them; returns the units and the force-gain unit (default N, or N m on a rotary axis, per
    input unit)."""
    _units.check(time_unit, "time", name="time_unit")
    _units.check(input_unit, "drive", name="input_unit")
    rotary = _units.is_rotary(output_unit, "position", name="output_unit")
    if force_gain_unit is None:
        force_gain_unit = _units.ratio("N m" if rotary else "N", input_unit)
    fg = _units.check(force_gain_unit, "force_gain", rotary=rotary, name="force_gain_unit")
    if _units.drive_base(input_unit, name="input_unit") != ("V" if fg.dim[5] else "A"):
        raise _units.UnitError(f"`force_gain_unit` {force_gain_unit!r} is per a different drive input than `input_unit` {input_unit!r}")
    units = {"a": f"{output_unit}/({input_unit} {time_unit}^2)", "b": f"1/{time_unit}", "c": f"1/{time_unit}^2", "delay": time_unit}
    return units, force_gain_unit


def plant_si(values: dict[str, float], units: dict[str, str]) -> Plant:
    """The :class:`~gmsfric.system.Plant` of parameters given in ``units``, in SI (``force_gain``
    must be among them)."""
    si = {k: _units.to_si(values[k], units[k], q, name=f"units[{k!r}]") for k, q in PLANT_QUANTITIES.items()}
    return Plant(si["a"], si["b"], si["c"], si["delay"], si["force_gain"])


@dataclass(frozen=True)
class Record:
    """The time series an FRF was estimated from and the Welch settings (data units)."""

    input: NDArray[np.float64]
    output: NDArray[np.float64]
    excitation: NDArray[np.float64] | None
    dt: float
    nperseg: int
    detrend: str | bool


class _WelchRatio:
    """``S_rx / S_ru`` of any signal ``x`` at chosen bins, with the Welch settings of a record
    (Hann, 50 % overlap, per-segment detrend): the model's response estimated exactly as the
    measured one was, so window leakage and the bias it causes near resonances and at the lowest
    bins cancel (the model is compared with the data through the same estimator)."""

    def __init__(self, record: Record, u: NDArray[np.float64], f: NDArray[np.float64]) -> None:
        n, m = u.size, record.nperseg
        step = m // 2
        self.starts = np.arange(0, n - m + 1, step)
        self.m = m
        self.window = signal.get_window("hann", m)
        self.detrend = record.detrend
        df = 1.0 / (m * record.dt)
        self.bins = np.rint(f / df).astype(int)
        tt = np.arange(m) - (m - 1) / 2.0
        self.tt = tt / np.sqrt(tt @ tt)
        ref = u if record.excitation is None else record.excitation
        self.R = self.spectra(ref[None, :])[0]
        self.S_ru = np.sum(np.conj(self.R) * self.spectra(u[None, :])[0], axis=0)

    def spectra(self, x: NDArray[np.float64]) -> NDArray[np.complex128]:
        """Windowed, detrended segment spectra at the bins: ``(rows, segments, bins)``."""
        seg = np.lib.stride_tricks.sliding_window_view(x, self.m, axis=-1)[:, self.starts, :]
        if self.detrend == "linear":
            seg = seg - seg.mean(axis=-1, keepdims=True)
            seg = seg - (seg @ self.tt)[..., None] * self.tt
        elif self.detrend == "constant":
            seg = seg - seg.mean(axis=-1, keepdims=True)
        return np.fft.rfft(seg * self.window, axis=-1)[..., self.bins]  # type: ignore[no-any-return]

    def ratio(self, x: NDArray[np.float64]) -> NDArray[np.complex128]:
        """``S_rx / S_ru`` per row of ``x``."""
        return np.sum(np.conj(self.R)[None] * self.spectra(x), axis=1) / self.S_ru  # type: ignore[no-any-return]


@dataclass
class FRF:
    """A measured frequency response.

    Attributes
    ----------
    f : ndarray
        Frequencies (cycles per time unit of the data, Hz for seconds).
    H : ndarray
        Complex response (output units per input unit).
    coherence : ndarray
        Magnitude-squared coherence in [0, 1].
    n_averages : int
        Number of Welch segments averaged.
    dt : float
        Sample period of the data.
    bin_correlation : float
        Variance inflation ``1 + 2 sum_k rho_k^2`` from the correlation ``rho_k`` of windowed DFT
        bins ``k`` apart (Hann: 1.94): errors of neighbouring H1 bins are correlated, so a
        parameter fitted over many bins is that much less certain than independent bins suggest.
    """

    f: NDArray[np.float64]
    H: NDArray[np.complex128]
    coherence: NDArray[np.float64]
    n_averages: int
    dt: float = 0.0
    bin_correlation: float = 1.0
    checks: dict[str, Any] = field(default_factory=dict)
    record: "Record | None" = field(default=None, repr=False)

    def select(self, fmin: float = 0.0, fmax: float = np.inf) -> "FRF":
        """The bins with ``fmin <= f <= fmax``."""
        m = (self.f >= fmin) & (self.f <= fmax)
        return FRF(self.f[m], self.H[m], self.coherence[m], self.n_averages, self.dt, self.bin_correlation, dict(self.checks), self.record)

    @property
    def stderr(self) -> NDArray[np.float64]:
        """Standard deviation of the real (and of the imaginary) part of each bin from the
        coherence, ``|H| sqrt((1-g^2)/(2 n g^2))``, the coherence capped at 0.9995 (no bin is taken
        as exact).  :func:`fit_plant` refines it from the output noise the fitted model leaves."""
        g = np.clip(self.coherence, 1e-6, COHERENCE_CAP)
        return np.abs(self.H) * np.sqrt((1 - g) / (2 * self.n_averages * g))  # type: ignore[no-any-return]

    def to_control(self) -> Any:
        """A python-control ``FrequencyResponseData`` (``control.frd``), omega in rad per time unit."""
        try:
            import control  # type: ignore[import-not-found]
        except ImportError as exc:  # pragma: no cover
            raise ImportError("python-control is not installed: pip install 'gmsfric[control]'") from exc
        m = self.f > 0
        return control.frd(self.H[m], 2 * np.pi * self.f[m])


def estimate_frf(
    t: ArrayLike | float,
    u: ArrayLike,
    y: ArrayLike,
    *,
    excitation: ArrayLike | None = None,
    nperseg: int | None = None,
    detrend: str = "linear",
) -> FRF:
    """H1 estimate with coherence (Welch averaging).

    Parameters
    ----------
    t : array_like or float
        Sample times (uniform) or the sample rate.
    u, y : array_like
        Input (drive command) and output (position).
    excitation : array_like, optional
        External excitation for closed-loop data: ``H = S_ry / S_ru`` and the coherence of
        ``r -> y``.
    nperseg : int, optional
        Segment length; default ``2^floor(log2(n / 16))`` (>= 16 averages at 50 % overlap).
    detrend : str
        Detrending of each segment (``"linear"`` removes drift in open-loop position records).
    """
    u = measured_signal("input", u, min_len=64)
    y = measured_signal("output", y)
    same_length("output", y, "input", u.size)
    if np.isscalar(t):
        fs = positive("sample_rate", float(t))  # type: ignore[arg-type]
        step("1 / sample_rate", 1.0 / fs)
    else:
        tt = measured_signal("time", t)
        same_length("time", tt, "input", u.size)
        d = np.diff(tt)
        if np.any(d <= 0):
            raise InvalidInputError("`time` must increase strictly")
        if np.ptp(d) > 1e-3 * np.median(d):
            raise InvalidInputError("`time` must be uniformly sampled for the FRF (resample first)")
        fs = 1.0 / step("time step", float(np.mean(d)))
    n = u.size
    if nperseg is None:
        nperseg = int(2 ** np.floor(np.log2(max(n / 16, 32))))
    nperseg = int(min(nperseg, n))
    if np.ptp(u) == 0:
        raise IdentificationError("the input is constant: no excitation to estimate a frequency response from")
    ref = u if excitation is None else measured_signal("excitation", excitation)
    same_length("excitation", ref, "input", n)
    # Spectra of the records scaled to unit peak at unit sample rate: H and the coherence are
    # ratios that do not depend on either scale, and extreme units or rates cannot then
    # underflow or overflow the spectra.
    s_ref, s_u, s_y = (float(np.max(np.abs(a))) or 1.0 for a in (ref, u, y))
    ref_n, y_n = ref / s_ref, y / s_y
    kw = dict(fs=1.0, nperseg=nperseg, detrend=detrend, window="hann")
    f, p_rr = signal.welch(ref_n, **kw)
    f = f * fs
    _, p_yy = signal.welch(y_n, **kw)
    _, p_ry = signal.csd(ref_n, y_n, **kw)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        if excitation is None:
            H = p_ry / p_rr * (s_y / s_u)
        else:
            _, p_ru = signal.csd(ref_n, u / s_u, **kw)
            H = p_ry / p_ru * (s_y / s_u)
        coh = np.nan_to_num(np.abs(p_ry) ** 2 / (p_rr * p_yy), nan=0.0)
    n_avg = max(1, int((n - nperseg) // (nperseg // 2) + 1))
    # a bin without input power has no response to estimate
    m = (f > 0) & np.isfinite(H)
    if not m.any():
        raise IdentificationError("no frequency of the record carries input power: no frequency response to estimate")
    win = signal.get_window("hann", nperseg)
    w2 = win**2
    k = np.arange(nperseg)
    rho = [abs(np.sum(w2 * np.exp(-2j * np.pi * j * k / nperseg))) / np.sum(w2) for j in range(1, 4)]
    # findings about the data the fit will report: a clipped drive, feedback in open-loop data
    pre = Findings()
    check_saturation(pre, "the input", u)
    if excitation is None:
        _check_feedback_open_loop(pre, u, y)
    checks: dict[str, Any] = {"closed_loop": excitation is not None, "findings": list(pre.items)}
    record = Record(u, y, None if excitation is None else ref, 1.0 / fs, nperseg, detrend)
    return FRF(f[m], H[m], np.clip(coh[m], 0.0, 1.0), n_avg, 1.0 / fs, 1.0 + 2.0 * float(np.sum(np.square(rho))), checks, record)


def _check_feedback_open_loop(findings: Findings, u: NDArray[np.float64], y: NDArray[np.float64]) -> None:
    """The feedback check of open-loop data.  A periodic input is tested on the parts of input
    and output that do not repeat: the repeating part of the output is a deterministic response
    that the check's short ARX model misses, and the future inputs, periodic, "explain" that
    misfit on any open-loop record; feedback acts through the output's noise, which does not
    repeat.  An input that repeats exactly cannot react to that noise at all."""
    per = _periodic_reference(u)
    if per is None or per.count < 2:
        check_feedback(findings, u, y)
        return
    seg = slice(per.first, per.first + per.count * per.period)
    uu = u[seg].reshape(per.count, per.period)
    yy = y[seg].reshape(per.count, per.period)
    u_np = (uu - uu.mean(axis=0)).ravel()
    if not np.std(u_np) > 1e-9 * np.std(u[seg]):
        return
    check_feedback(findings, u_np, (yy - yy.mean(axis=0)).ravel())


def zoh_factor(f: NDArray[np.float64], dt: float) -> NDArray[np.complex128]:
    """Zero-order hold ``(1 - exp(-s dt)) / (s dt)`` at ``s = 2 pi i f`` (1 for ``dt = 0``)."""
    if dt <= 0:
        return np.ones_like(f, dtype=complex)
    s = 2j * np.pi * f
    return (1 - np.exp(-s * dt)) / (s * dt)


def plant_response(f: NDArray[np.float64], a: float, b: float, c: float, delay: float, dt: float = 0.0) -> NDArray[np.complex128]:
    """``a / (s^2 + b s + c) exp(-s delay)`` at ``s = 2 pi i f``; with ``dt > 0`` the response of
    that plant driven through a zero-order hold and sampled every ``dt`` (the exact step-invariant
    discretisation, fractional delay included: what sampled data obey, aliasing and all;
    :meth:`gmsfric.system.Plant.frequency_response`).  Any consistent units."""
    if dt > 0:
        return Plant(a, b, c, delay).frequency_response(f, dt)
    s = 2j * np.pi * f
    return a / (s * s + b * s + c) * np.exp(-s * delay)  # type: ignore[no-any-return]


def _levy(f: NDArray[np.float64], H: NDArray[np.complex128], w: NDArray[np.float64], tau: float) -> NDArray[np.float64] | None:
    s = 2j * np.pi * f
    scale = w / np.maximum(np.abs(H * s * s), 1e-300)
    cols = np.stack([np.exp(-s * tau), -s * H, -H], axis=1) * scale[:, None]
    rhs = H * s * s * scale
    A = np.concatenate([cols.real, cols.imag])
    bvec = np.concatenate([rhs.real, rhs.imag])
    try:
        sol, *_ = np.linalg.lstsq(A, bvec, rcond=None)
    except np.linalg.LinAlgError:  # pragma: no cover
        return None
    return sol


def fit_plant(
    frf: FRF,
    *,
    fmin: float = 0.0,
    fmax: float = np.inf,
    min_coherence: float = 0.3,
    max_delay: float | None = None,
    fit_delay: bool = True,
    delay: float = 0.0,
    force_gain: float | None = None,
    zoh: bool = True,
    time_unit: str = "s",
    input_unit: str = "V",
    output_unit: str = "m",
    force_gain_unit: str | None = None,
) -> IdentificationResult:
    """Fit ``a / (s^2 + b s + c) exp(-s delay)`` to an FRF (coherence-weighted NLS).

    Parameters
    ----------
    frf : FRF
        From :func:`estimate_frf`, in the data's units (below).
    fmin, fmax : float
        Frequency band of the fit (1/time unit).
    min_coherence : float
        Bins below this coherence are left out.
    max_delay : float, optional
        Upper end of the delay search (time unit; the delay is bounded by 1.5 times it); default
        what the phases of adjacent excited lines can tell apart, ``0.5 / spacing``: the spacing
        of the fitted bins or, with a periodic excitation (a multisine repeating every ``P``
        samples), of its excited harmonics, as delays a whole period apart fit its lines alike.
        Refused beyond ``0.5 / spacing`` of the FRF's bins, where no search can tell delays apart.
        Another delay that fits about as well is reported (``delay_ambiguous``).
    fit_delay : bool
        Fit the delay (else hold it at ``delay``, time unit).
    force_gain : float, optional
        Force per drive-input unit (the motor constant), in ``force_gain_unit``: not identifiable
        from an FRF, carried into the returned :class:`~gmsfric.system.Plant` and the JSON.
        Without it the ``model_object`` carries 1 (so friction would enter unscaled) and the
        JSON's model document states no force gain, so it cannot be loaded as a Plant.
    zoh : bool
        Fit the plant as sampled data see it: driven through a zero-order hold and sampled at the
        FRF's rate (exact discretisation, fractional delay included), so ``delay`` is the plant's
        own and no aliasing bias remains near the Nyquist frequency.  ``False`` fits the
        continuous response and lumps the hold into ``delay`` (about half a sample more), as a
        plain continuous fit of the paper's kind would.
    time_unit, input_unit, output_unit : str
        Units of the data (any :mod:`gmsfric.units` reads).  The FRF is converted to SI before
        the fit; the parameters are reported in these units, ``model_object`` is in SI.
    force_gain_unit : str, optional
        Unit of ``force_gain``; default ``N/<input_unit>`` (``N m/<input_unit>`` when the output
        is an angle).

    Returns
    -------
    IdentificationResult
        ``model="plant"``, parameters ``a b c delay``; ``model_object`` a ``Plant`` in SI.
        ``info`` includes ``excitation_period`` (time unit, ``None`` unless the reference
        repeats), ``delay_limit`` and ``output_resolution`` (the output's quantization step,
        ``None`` when it is not quantized): with a periodic excitation the repeating
        quantization error is part of the bins' noise.

    Raises
    ------
    UnitError
        A unit unknown or not of its quantity (before any work).
    InvalidInputError
        ``force_gain`` or ``max_delay`` not positive and finite, or ``max_delay`` beyond what
        the bins resolve.
    IdentificationError
        Fewer than 8 usable bins in the band.
    """
    units, force_gain_unit = plant_units(time_unit, input_unit, output_unit, force_gain_unit)
    if force_gain is not None:
        force_gain = positive("force_gain", force_gain)
    if max_delay is not None:
        max_delay = positive("max_delay", max_delay)
    kt = _units.factor(time_unit, "time", name="time_unit")
    k_h = _units.factor(output_unit, "position", name="output_unit") / _units.factor(input_unit, "drive", name="input_unit")
    sel = frf.select(fmin, fmax)
    m = sel.coherence >= min_coherence
    # the fit runs in SI: frequencies in Hz, response in m/V (or rad/A ...)
    f, H, sd = sel.f[m] / kt, sel.H[m] * k_h, sel.stderr[m] * k_h
    if f.size < 8:
        raise IdentificationError(f"only {f.size} frequency bins with coherence >= {min_coherence} in the band: need at least 8 (more excitation or a longer record)")
    resolvable = 0.5 / float(np.min(np.diff(sel.f)))
    if max_delay is not None and max_delay > resolvable:
        # beyond it the phases of adjacent bins no longer tell delays apart: the search would
        # pick one of several equally good delays
        raise InvalidInputError(f"`max_delay` = {max_delay:g} {time_unit} is beyond the longest delay the FRF's bins resolve, "
                                f"{resolvable:g} {time_unit} (half the inverse of their spacing); a longer segment (nperseg) resolves longer delays")
    sd = np.maximum(sd, 1e-12 * np.abs(H))
    T = sel.dt * kt if zoh else 0.0
    # a periodic excitation (multisine) carries information only at its lines: delays a whole
    # period apart fit them alike, so the search ends at half the spacing of the excited lines
    per = None if sel.record is None else _periodic_reference(sel.record.input if sel.record.excitation is None else sel.record.excitation)
    line_spacing = period_si = None
    f_d, H_d, sd_d = f, H, sd
    if per is not None:
        fk = per.excited / (per.period * sel.dt)
        in_band = (fk >= sel.f[m].min() * (1 - 1e-9)) & (fk <= sel.f[m].max() * (1 + 1e-9))
        k_band = per.excited[in_band]
        line_spacing = float(np.min(np.diff(k_band)) if k_band.size > 1 else 1) / (per.period * sel.dt * kt)
        period_si = per.period * sel.dt * kt
        # Lines two bins apart or more: a bin next to a line holds that line's response (both
        # spectra leak alike), not the response at the bin's frequency, so the direct fit takes
        # one bin per line, at the line's frequency.
        df = 1.0 / (sel.record.nperseg * sel.dt * kt)  # type: ignore[union-attr]
        if line_spacing >= 2.0 * df:
            near = np.clip(np.searchsorted(f, fk[in_band] / kt), 1, f.size - 1)
            near = np.where(np.abs(f[near - 1] - fk[in_band] / kt) < np.abs(f[near] - fk[in_band] / kt), near - 1, near)
            on = np.abs(f[near] - fk[in_band] / kt) <= 0.5 * df
            near, on = np.unique(near[on], return_index=True)
            if near.size >= 8:
                f_d, H_d, sd_d = fk[in_band][on] / kt, H[near], sd[near]
    q, r = _fit_plant_si(f_d, H_d, sd_d, T, fit_delay, float(delay) * kt, None if max_delay is None else float(max_delay) * kt, sel.dt * kt,
                         line_spacing, period_si)
    r.n_bins = f_d.size
    resolution = None
    r_direct = r
    if zoh and sel.record is not None:
        # the same fit against the model's FRF estimated exactly as the measured one (leakage)
        k_u = _units.factor(input_unit, "drive", name="input_unit")
        q, r = _refine_matched(q, r, sel.record, sel.f[m], H, sd, kt, k_u, k_h * k_u, fit_delay, float(delay) * kt, per, period_si)
        resolution = getattr(r, "resolution", None)
    jac = r.jac if fit_delay else r.jac[:, :3]
    dof = max(2 * getattr(r, "n_bins", f.size) - (4 if fit_delay else 3), 1)
    chi2 = float(r.fun @ r.fun)
    matched = zoh and sel.record is not None
    # The bins' noise is the measurement's: the Jacobian covariance is scaled by chi2/dof only
    # within the range a right model reaches (a larger chi2 is a misfit, flagged below, that
    # wider error bars must not hide; the matched fit's noise may only be overestimated, where
    # leakage dominates, so it is not scaled down).
    ratio = chi2 / dof if chi2 > 0 else 1.0
    scale = float(np.clip(ratio, 1.0 if matched else 0.5, 2.0))
    s2_jac = chi2 / max(jac.shape[0] - jac.shape[1], 1) if chi2 > 0 else 1.0  # what covariance_from_jacobian scales by
    cov = covariance_from_jacobian(jac, r.fun) * (scale / s2_jac) * frf.bin_correlation
    se = np.sqrt(np.clip(np.diag(cov), 0, np.inf))
    a_si = float(np.exp(q[0]))
    tau_si = float(q[3]) if fit_delay else float(delay) * kt
    values_si = {"a": a_si, "b": float(q[1]), "c": float(q[2]), "delay": tau_si}
    se_si = {"a": a_si * se[0], "b": float(se[1]), "c": float(se[2]), "delay": float(se[3]) if fit_delay else 0.0}
    findings = Findings()
    for d in frf.checks.get("findings", []):
        findings.add(d.code, d.message, d.parameter)
    # parameters at their zero bound are reported as exactly zero (no relative error of a zero)
    upper_delay = r.bounds_hi[3] if fit_delay else None
    for name in ("b", "c", "delay"):
        if name == "delay" and not fit_delay:
            continue
        scale = max(se_si[name], 1e-12 * {"b": 2 * np.pi * f.max(), "c": (2 * np.pi * f.max()) ** 2, "delay": 1.0 / f.max()}[name])
        if values_si[name] <= 1e-6 * scale or values_si[name] == 0.0:
            values_si[name] = 0.0
            what = {"b": ": the data show no damping (or ask for a negative one)", "c": ": the data ask for a negative stiffness or do not show one",
                    "delay": ": no delay found (or the band is too low to see it)"}[name]
            findings.add("at_bound", f"{name} is at its lower bound 0{what}", name)
    if fit_delay and upper_delay is not None:
        end = (" (the delay search's end, half the period of the excitation's line spacing: delays a whole period apart fit its "
               "lines alike; give max_delay to search further)" if line_spacing is not None and max_delay is None
               else " (the delay search's end: give --fmax or a longer band)")
        check_bounds(findings, "delay", tau_si, None, float(upper_delay), what=end)
        # another delay that fits about as well (beyond the estimate's own uncertainty): the data
        # cannot tell them apart, whichever the fit returned
        tol = 4.0 * max(1.0, chi2 / dof)
        alternatives = list(getattr(r, "alternatives", []))
        if r is not r_direct:
            # whole excitation periods apart, on the direct fit's lines: the matched fit's
            # simulated start from rest would tell them apart, the steady-state data do not
            base = r_direct.direct_chi2(q)
            alternatives += [(float(x[3]), r_direct.direct_chi2(x) - base) for x in _period_shifts(q, period_si, float(upper_delay))]
        near = sorted((t, d) for t, d in alternatives if abs(t - tau_si) > max(4.0 * se_si["delay"], sel.dt * kt) and d < tol)
        if near:
            why = (f": the excitation repeats every {per.period} samples, so delays a whole period apart fit its lines alike; give a "
                   "max_delay below the period, or an excitation with a longer period" if per is not None else
                   ": the data do not tell these delays apart (a longer record or a wider band may)")
            others = ", ".join(f"{t / kt:.4g}" for t, _ in near)
            findings.add("delay_ambiguous", f"delay = {values_si['delay'] / kt:.4g} {time_unit} fits about as well as {others} {time_unit} "
                                            f"(chi2 within {max(abs(d) for _, d in near):.2g} of it){why}", "delay")
    # with the record, leakage can make the bins' noise an overestimate: only a large chi2 means something
    check_chi2(findings, chi2, dof, what=" of the FRF fit",
               low=None if matched else 0.5, rescaled=False)
    check_stderr(findings, {k: (values_si[k], se_si[k]) for k in PLANT_NAMES}, skip={k for k in PLANT_NAMES if values_si[k] == 0.0})
    fn = np.sqrt(values_si["c"]) / (2 * np.pi)
    if values_si["c"] > 0 and fn < f.min() / 10:
        findings.add("coverage", f"c: the natural frequency {fn:.3g} Hz lies far below the lowest fitted bin {f.min():.3g} Hz (c is poorly determined)", "c")
    # report in the data's units (the edge)
    fac = {k: _units.factor(units[k], PLANT_QUANTITIES[k], name=f"units[{k!r}]") for k in PLANT_NAMES}
    params = {k: (values_si[k] / fac[k], se_si[k] / fac[k]) for k in PLANT_NAMES}
    info = {"zoh_dt": sel.dt if zoh else 0.0, "model": "sampled" if zoh else "continuous", "n_bins": int(f.size), "n_bins_weighted": int(getattr(r, "n_bins", f.size)),
            "band": [float(sel.f[m].min()), float(sel.f[m].max())], "chi2_per_dof": chi2 / dof, "n_averages": frf.n_averages,
            "excitation_period": None if per is None else per.period * sel.dt, "delay_limit": None if upper_delay is None else float(upper_delay) / kt,
            "output_resolution": resolution}
    info["force_gain"] = force_gain
    if force_gain is not None:
        units["force_gain"] = force_gain_unit
    fg_si = 1.0 if force_gain is None else _units.to_si(force_gain, force_gain_unit, "force_gain", name="force_gain_unit")
    plant = Plant(values_si["a"], values_si["b"], values_si["c"], values_si["delay"], fg_si)
    # covariance of (a, b, c, delay) from that of (log a, b, c[, delay]); a held delay has none
    jac_p = np.eye(4)[:, : cov.shape[0]] * np.array([a_si, 1.0, 1.0, 1.0])[:, None]
    cov_si = transform_covariance(cov, jac_p)
    inv = np.array([1.0 / fac[k] for k in PLANT_NAMES])
    res = IdentificationResult("plant", params, units, info,
                               data={"frf": frf, "fit_f": sel.f[m], "input_unit": input_unit, "output_unit": output_unit, "zoh": zoh},
                               model_object=plant, covariance=(list(PLANT_NAMES), cov_si * np.outer(inv, inv)))
    emit(res, findings)
    return res


def _refine_matched(q0: NDArray[np.float64], r0: Any, record: Record, f_data: NDArray[np.float64], H: NDArray[np.complex128], sd: NDArray[np.float64],
                    kt: float, k_u: float, k_y: float, fit_delay: bool, delay: float, per: _Periodic | None = None,
                    period: float | None = None) -> tuple[NDArray[np.float64], Any]:
    """NLS of ``(log a, b, c, delay)`` where the model's response is the Welch estimate of the
    sampled plant's simulated output for the recorded input (in SI), at the fitted bins.

    With a periodic excitation ``per`` and a quantized output, the bins' noise includes the bias
    the repeating quantization error leaves (:func:`_periodic_error_sd`).  The result's
    ``alternatives`` are ``(delay, chi2 - chi2_best)`` on this objective of the direct fit's other
    optima and of the delay shifted by whole excitation periods (``period``, SI)."""
    u_si = record.input * k_u
    dt_si = record.dt * kt
    welch = _WelchRatio(record, u_si, f_data)
    H_meas = welch.ratio(record.output[None, :] * k_y)[0]
    n_q = 4 if fit_delay else 3
    lo, hi = np.array([-np.inf, 0.0, 0.0, 0.0]), np.asarray(r0.bounds_hi, dtype=float).copy()
    # log a within ten decades of the direct fit: a step beyond cannot describe the same data
    # and would overflow the simulated plant
    lo[0], hi[0] = q0[0] - 23.0, q0[0] + 23.0
    lo, hi = lo[:n_q], hi[:n_q]
    scale = np.array([1.0, 2 * np.pi * f_data.min() / kt, (2 * np.pi * f_data.min() / kt) ** 2, dt_si])[:n_q]

    def plants(qs: list[NDArray[np.float64]]) -> list[Plant]:
        return [Plant(float(np.exp(q[0])), float(q[1]), float(q[2]), float(q[3]) if fit_delay else delay) for q in qs]

    def model(qs: list[NDArray[np.float64]]) -> NDArray[np.complex128]:
        try:
            y = simulate_batch(plants(qs), None, None, None, dt_si, feedforward=u_si, record=("position",), threads=1, progress=False).position
        except (InvalidInputError, SimulationError):
            # a trial plant the core refuses (too fast for the step, diverging): far from the data
            return np.full((len(qs), f_data.size), 1e6 * np.max(np.abs(H_meas)) + 1.0, dtype=complex)
        return welch.ratio(y)

    def stack(e: NDArray[np.complex128]) -> NDArray[np.float64]:
        return np.concatenate([e.real, e.imag], axis=-1)  # type: ignore[no-any-return]

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return stack((model([q])[0] - H_meas) / sd)

    def jac(q: NDArray[np.float64]) -> NDArray[np.float64]:
        steps = 1e-6 * np.maximum(np.abs(q), scale)
        qs = [q]
        for i in range(n_q):
            qi = q.copy()
            # a forward step off a lower bound of zero, else backward near the upper bound
            qi[i] += steps[i] if q[i] + steps[i] <= hi[i] else -steps[i]
            qs.append(qi)
        Hs = model(qs)
        cols = [stack((Hs[i + 1] - Hs[0]) / sd) / (qs[i + 1][i] - q[i]) for i in range(n_q)]
        return np.column_stack(cols)

    # the direct fit's b and c can be far off where leakage biased it (resonances below or at the
    # lowest bins): a few rescaled starts, judged on this objective, the two best polished
    starts = []
    for fb in (1.0, 0.1):
        for fc in (1.0, 0.1, 0.01, 0.0, 10.0):
            qs = q0[:n_q].copy()
            qs[1] *= fb
            qs[2] *= fc
            starts.append(np.clip(qs, lo, hi))
    costs = [float(np.sum(v**2)) for v in (stack((h - H_meas) / sd) for h in model(starts))]
    sol = None
    for i in np.argsort(costs)[:2]:
        cand = least_squares(resid, starts[i], jac=jac, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=40)
        if sol is None or cand.cost < sol.cost:
            sol = cand
    assert sol is not None
    # The bins' standard deviation from the measurement, not from the fitted model's residual (a
    # wrong model would widen its own error bars and hide its misfit): the output power not
    # coherent with the reference, less the part window leakage alone leaves incoherent (the
    # noise-free model's output through the same segments; it cancels in this comparison).  The
    # model can only lower it, never below a floor, and never above the coherence bound.
    q_step = quantum(record.output) or None
    floor = None if per is None or q_step is None else _periodic_error_sd(per, u_si, record.output * k_y, q_step * k_y, welch.bins, record.nperseg)
    S_rr = np.mean(np.abs(welch.R) ** 2, axis=0)

    def measured_noise(x: NDArray[np.float64]) -> None:
        y_fit = simulate_batch(plants([x]), None, None, None, dt_si, feedforward=u_si, record=("position",), threads=1, progress=False).position
        sd[:] = _matched_stderr(welch, record.output * k_y, y_fit[0], H_meas, open_loop=record.excitation is None)
        if floor is not None:
            sd[:] = np.hypot(sd, floor)
        # a bin the reference does not excite (between or beside a multisine's lines) holds a ratio of
        # leakage residues that any small parameter error changes by far more than the noise: no data
        idle = S_rr < 1e-6 * np.median(S_rr)
        if per is not None:
            # with a periodic reference, a bin more than two bins from every excited line holds only
            # the ratio of noise to leakage residue, whatever its reference power
            lines = per.excited * (record.nperseg / per.period)
            pos = np.clip(np.searchsorted(lines, welch.bins), 1, lines.size - 1) if lines.size > 1 else np.zeros(welch.bins.size, dtype=int)
            gap = np.minimum(np.abs(welch.bins - lines[pos]), np.abs(welch.bins - lines[np.maximum(pos - 1, 0)]))
            idle |= gap > 2.0
        if idle.sum() <= sd.size - 8:
            sd[idle] = np.inf

    measured_noise(sol.x)
    sol = least_squares(resid, sol.x, jac=jac, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=20)
    alternatives: list[tuple[float, float, NDArray[np.float64]]] = []
    if fit_delay:
        # the direct fit's other optima and the delay shifted by whole excitation periods, on this
        # objective: one that fits better is taken (the direct fit cannot tell such delays apart,
        # the simulated start transient here may), one about as good is reported
        pool = [np.clip(np.asarray(x, dtype=float)[:n_q], lo, hi) for x in getattr(r0, "others", [])]
        for attempt in range(3):
            cands = [x for x in pool + _period_shifts(sol.x, period, float(hi[3])) if abs(x[3] - sol.x[3]) > dt_si]
            alternatives = []
            chi2_best = 2.0 * sol.cost
            for x, h in zip(cands, model(cands) if cands else []):
                d = float(np.sum(stack((h - H_meas) / sd) ** 2)) - chi2_best
                if d < 100.0:  # judged once polished here
                    rr = least_squares(resid, x, jac=jac, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=10)
                    if 2.0 * rr.cost - chi2_best < d:
                        x, d = rr.x, 2.0 * rr.cost - chi2_best
                if abs(x[3] - sol.x[3]) > dt_si:
                    alternatives.append((float(x[3]), d, x))
            better = min(alternatives, key=lambda a: a[1], default=None)
            if better is None or better[1] >= 0.0 or attempt == 2:
                break
            pool = [sol.x] + [a[2] for a in alternatives if a is not better]
            # the bins' noise depends on the fitted model (leakage): measured again for this one
            measured_noise(better[2])
            sol = least_squares(resid, better[2], jac=jac, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=20)
    sol.alternatives = [(t, d) for t, d, _ in alternatives]
    sol.resolution = q_step
    q = np.concatenate([sol.x, q0[n_q:]])
    sol.bounds_hi = r0.bounds_hi
    sol.n_bins = int(np.sum(np.isfinite(sd)))
    if not fit_delay:
        sol.jac = np.column_stack([sol.jac, np.zeros(sol.jac.shape[0])])
    return q, sol


def _matched_stderr(welch: _WelchRatio, y: NDArray[np.float64], y_model: NDArray[np.float64], H: NDArray[np.complex128],
                    open_loop: bool = True) -> NDArray[np.float64]:
    """Standard deviation of the real (and imaginary) part of the Welch ratio at each bin from the
    output noise, ``var(H) = S_rr E / (n |S_ru|^2)`` with ``E`` the output power incoherent with
    the reference ``r`` (Bendat & Piersol).  ``E`` is the measured one less that of ``y_model``
    (leakage, the same for model and data; open loop only), at least ``E / n`` (``n`` segments: about the scatter
    of that difference where leakage dominates)."""
    R = welch.R
    n = R.shape[0]
    S_rr = np.mean(np.abs(R) ** 2, axis=0)

    def incoherent(x: NDArray[np.float64]) -> NDArray[np.float64]:
        X = welch.spectra(x[None, :])[0]
        return np.maximum(np.mean(np.abs(X) ** 2, axis=0) - np.abs(np.mean(np.conj(R) * X, axis=0)) ** 2 / S_rr, 0.0)  # type: ignore[no-any-return]

    e_meas = incoherent(y) * n / max(n - 1, 1)  # one complex coefficient per bin fitted away
    # with feedback the noise enters the input too and is no longer independent of the model's
    # output: no subtraction there (the coherence bound)
    e_leak = incoherent(y_model) * n / max(n - 1, 1) if open_loop else 0.0
    e_noise = np.clip(e_meas - e_leak, e_meas / n, e_meas)
    sd = np.sqrt(S_rr * e_noise / (2 * n * np.abs(welch.S_ru / n) ** 2))
    return np.maximum(sd, 1e-9 * np.abs(H))  # type: ignore[no-any-return]


@dataclass(frozen=True)
class _Periodic:
    """A reference that repeats every ``period`` samples: the data then carry information only at
    its harmonics ``k / (period dt)``, ``excited`` those with power; ``first`` and ``count`` the
    whole periods averaged (the first skipped when there are enough: the start transient)."""

    period: int
    excited: NDArray[np.int_]
    first: int
    count: int

    def coefficients(self, x: NDArray[np.float64]) -> tuple[NDArray[np.complex128], NDArray[np.float64]]:
        """Fourier coefficients of the period-averaged ``x`` (harmonics ``0 .. period // 2``) and
        the variance of each from the scatter between periods (the part that does not repeat)."""
        seg = x[self.first:self.first + self.count * self.period].reshape(self.count, self.period)
        C = np.fft.rfft(seg, axis=1) / self.period
        c = C.mean(axis=0)
        var = np.sum(np.abs(C - c) ** 2, axis=0) / (self.count * max(self.count - 1, 1))
        return c, var  # type: ignore[return-value]


def _periodic_reference(r: NDArray[np.float64], min_correlation: float = 0.95) -> _Periodic | None:
    """The period of a reference that repeats every whole number of samples (a periodic
    multisine), or ``None``: the first lag, after the autocorrelation fell below 0.5, where it
    exceeds ``min_correlation``, and again at the next multiples (a narrow-band random signal
    correlates at one lag but not at its multiples)."""
    x = signal.detrend(np.asarray(r, dtype=float))
    n = x.size
    if n < 64 or not np.any(x):
        return None
    nfft = int(2 ** np.ceil(np.log2(2 * n)))
    ac = np.fft.irfft(np.abs(np.fft.rfft(x, nfft)) ** 2, nfft)[: n // 2 + 1]
    cs = np.concatenate(([0.0], np.cumsum(x * x)))
    lags = np.arange(n // 2 + 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = ac / np.sqrt(cs[n - lags] * (cs[n] - cs[lags]))
    rho = np.nan_to_num(rho)
    dipped = np.flatnonzero(rho < 0.5)
    if dipped.size == 0:
        return None
    above = np.flatnonzero((rho >= min_correlation) & (lags > dipped[0]))
    if above.size == 0:
        return None
    run_end = above[0]
    while run_end + 1 < rho.size and rho[run_end + 1] >= min_correlation:
        run_end += 1
    period = int(above[0] + np.argmax(rho[above[0]:run_end + 1]))
    if any(rho[j * period] < min_correlation for j in range(2, 5) if j * period < rho.size):
        return None
    count = n // period
    first = 1 if count >= 4 else 0
    per = _Periodic(period, np.zeros(0, dtype=int), first * period, count - first)
    c, var = per.coefficients(x)
    power = np.abs(c) ** 2
    power[0] = 0.0
    # a harmonic carries excitation when it stands well above the scatter between periods
    excited = np.flatnonzero(power > np.maximum(100.0 * np.median(var), 1e-8 * power.max()))
    if excited.size == 0:
        return None
    return _Periodic(period, excited, per.first, per.count)


def _periodic_error_sd(per: _Periodic, u: NDArray[np.float64], y: NDArray[np.float64], q: float, bins: NDArray[np.int_],
                       nperseg: int) -> NDArray[np.float64] | None:
    """Standard deviation (real and imaginary part) of the bias a periodic output error leaves in
    the Welch ratio at each bin: with a periodic excitation, quantizing the output with step
    ``q`` gives an error that repeats every period, so it is coherent with the reference and
    averaging segments does not reduce it (nor does the incoherent power show it).  Its level per
    harmonic is measured where nothing is excited (the period-averaged output less the scatter
    between periods; without 8 such harmonics, taken at the cap) and capped at what the quantization can give,
    ``q^2 / 12`` spread evenly over the ``period`` harmonics (so a larger distortion stays a
    misfit); at a bin, the harmonics near it are weighted by the Hann window's response."""
    P = per.period
    cu, _ = per.coefficients(u)
    cy, var_y = per.coefficients(signal.detrend(y))
    free = np.ones(cy.size, dtype=bool)
    free[per.excited] = False
    free[:3] = False  # the lowest harmonics hold what a linear detrend leaves of drift
    # the error's spectrum need not be flat (nor is a trend that does not repeat absent from the
    # period average): the mean over all unexcited harmonics, never above the cap, errs on the
    # side of a larger noise
    v = float(np.mean(np.abs(cy[free]) ** 2 - var_y[free])) if free.sum() >= 8 else np.inf
    v = min(max(v, 0.0), q * q / (12.0 * P))
    if v <= 0.0:
        return None
    # harmonics within 4 bins of each bin: offset nu = k nperseg / P - bin (in bins)
    ratio = nperseg / P
    k0 = np.floor((bins - 4.0) / ratio).astype(int)
    kk = k0[:, None] + np.arange(int(np.ceil(8.0 / ratio)) + 2)[None, :]
    inside = (kk >= 1) & (kk < cu.size)
    nu = kk * ratio - bins[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(np.abs(np.abs(nu) - 1.0) < 1e-9, 0.5, np.sinc(nu) / (1.0 - nu * nu))
    w2 = np.where(inside & (np.abs(nu) <= 4.0), w * w, 0.0)
    den = np.sum(w2 * np.abs(cu[np.clip(kk, 0, cu.size - 1)]) ** 2, axis=1)
    out = np.zeros(bins.size)
    good = den > 0
    out[good] = np.sqrt(v * np.sum(w2[good], axis=1) / (2.0 * den[good]))
    return out


def _fit_plant_si(f: NDArray[np.float64], H: NDArray[np.complex128], sd: NDArray[np.float64], T: float, fit_delay: bool, delay: float,
                  max_delay: float | None, dt_data: float = 0.0, line_spacing: float | None = None,
                  period: float | None = None) -> tuple[NDArray[np.float64], Any]:
    """NLS of ``(log a, b, c, delay)`` on the SI FRF from the best starts of two searches.

    * Levy's continuous linear fit on a grid of delays over two periods of the highest bin (or
      ``max_delay``), as the paper would start it.
    * The exact sampled model's linear fit for every whole number of delay samples up to
      ``max_delay`` or, without it, to what the phases of adjacent excited lines can tell apart,
      ``0.5 / spacing`` (``line_spacing`` of a periodic excitation's lines, else that of the
      bins): the cost has a local minimum every period of the highest bin, so only a search over
      the whole plausible range finds the global one; a continuous fit cannot serve there, as
      the sampled response departs from it near the Nyquist frequency.

    Without ``max_delay`` the delay is bounded by that limit (beyond it, delays a whole number of
    excitation periods apart fit the same lines equally well); with it, by ``1.5 max_delay``.
    The result's ``alternatives`` lists ``(delay, chi2 - chi2_best)`` of the other optima found
    and of the delay shifted by whole excitation ``period`` s within the bounds.
    """
    limit = 0.5 / float(np.min(np.diff(f))) if f.size > 1 else 2.0 / f.max()
    if line_spacing is not None and line_spacing > 0:
        limit = min(limit, 0.5 / line_spacing)
    if max_delay is None:
        span, upper, bound = min(2.0 / f.max(), limit), limit, limit
    else:
        span = upper = max_delay
        bound = 1.5 * max_delay
    dt_s = dt_data if dt_data > 0 else T
    extra: list[tuple[float, NDArray[np.float64]]] = []
    if fit_delay and dt_s > 0:
        extra = _sampled_starts(f, H, sd, T, dt_s, upper)
    return _fit_plant_delay_span(f, H, sd, T, fit_delay, delay, span, extra, bound, period)


def _sampled_starts(f: NDArray[np.float64], H: NDArray[np.complex128], sd: NDArray[np.float64], T: float, dt: float, max_delay: float,
                    n_keep: int = 6) -> list[tuple[float, NDArray[np.float64]]]:
    """Starts ``(cost, (log a, b, c, delay))`` from the linear fit of the ZOH-sampled plant,
    ``H (1 + d1 w + d2 w^2) = w^(m+1) (n0 + n1 w + n2 w^2)`` with ``w = exp(-s dt)``, exact for a
    delay of ``m`` to ``m + 1`` samples, solved for every ``m`` up to ``max_delay / dt`` at once.

    The ``n_keep`` best local minima over ``m`` are refined by Sanathanan-Koerner iterations
    (reweighting by the fitted denominator), mapped to ``b, c`` through the poles, and the
    fractional delay and ``a`` are profiled on the model the fit uses (``T``: 0 continuous)."""
    m_max = int(min(max_delay / dt, 20000))
    g2 = 1.0 / sd**2  # the equation error is the model error times the denominator: reweighted below
    phase = 2 * np.pi * f * dt
    w = np.exp(-1j * phase)
    # S(p) = sum g^2 conj(H) w^p, p = -2 .. m_max + 3
    p_all = np.arange(-2, m_max + 4)
    v = g2 * np.conj(H)
    S = np.empty(p_all.size, dtype=complex)
    W = np.exp(-1j * np.outer(np.arange(min(512, p_all.size)), phase))  # w^k for a block of p, shifted by w^p0
    for i0 in range(0, p_all.size, W.shape[0]):
        k = min(W.shape[0], p_all.size - i0)
        S[i0:i0 + k] = W[:k] @ (v * np.exp(-1j * p_all[i0] * phase))
    Sp = lambda p: S[p + 2]  # noqa: E731
    # m-independent blocks: equations H w^i (i = 1, 2), -w^(m+1+j) (j = 0..2), rhs -H
    hh = g2 * np.abs(H) ** 2
    F = np.array([[np.real(np.sum(hh * w ** (j - i))) for j in (1, 2)] for i in (1, 2)])
    N = np.array([[np.real(np.sum(g2 * w ** (j - i))) for j in range(3)] for i in range(3)])
    q_fixed = np.array([np.real(np.sum(hh * w ** i)) for i in (1, 2)])
    c0 = float(np.sum(hh))
    ms = np.arange(m_max + 1)
    M = np.zeros((ms.size, 5, 5))
    q = np.zeros((ms.size, 5))
    M[:, :2, :2] = F
    M[:, 2:, 2:] = N
    for i in (1, 2):
        for j in range(3):
            x = -np.real(Sp(ms + 1 + j - i))
            M[:, i - 1, 2 + j] = x
            M[:, 2 + j, i - 1] = x
    q[:, :2] = q_fixed
    for j in range(3):
        q[:, 2 + j] = -np.real(np.conj(Sp(ms + 1 + j)))
    with np.errstate(all="ignore"):
        try:
            x = np.linalg.solve(M + 1e-12 * np.trace(M, axis1=1, axis2=2)[:, None, None] * np.eye(5), -q[..., None])[..., 0]
        except np.linalg.LinAlgError:  # pragma: no cover
            return []
        cost = c0 + np.einsum("ki,ki->k", q, x)
    cost = np.where(np.isfinite(cost), cost, np.inf)
    # local minima over m, best first
    mins = [k for k in range(ms.size) if (k == 0 or cost[k] <= cost[k - 1]) and (k == ms.size - 1 or cost[k] <= cost[k + 1])]
    mins = sorted(mins, key=lambda k: cost[k])[:n_keep]
    out = []
    for k in mins:
        m = int(ms[k])
        cols = np.stack([H * w, H * w**2, -w ** (m + 1), -w ** (m + 2), -w ** (m + 3)], axis=1)
        g = np.sqrt(g2)
        sol = x[k]
        for _ in range(4):  # Sanathanan-Koerner: the equation error divided by the last denominator
            den = np.abs(1 + sol[0] * w + sol[1] * w**2)
            gk = g / np.maximum(den, 1e-12 * den.max() + 1e-300)
            A = cols * gk[:, None]
            try:
                sol, *_ = np.linalg.lstsq(np.concatenate([A.real, A.imag]), np.concatenate([(-H * gk).real, (-H * gk).imag]), rcond=None)
            except np.linalg.LinAlgError:  # pragma: no cover
                break
        start = _continuous_from_sampled(f, H, sd, T, dt, m, sol[0], sol[1])
        if start is not None:
            out.append(start)
    return out


def _continuous_from_sampled(f: NDArray[np.float64], H: NDArray[np.complex128], sd: NDArray[np.float64], T: float, dt: float, m: int,
                             d1: float, d2: float) -> tuple[float, NDArray[np.float64]] | None:
    """``b, c`` from the poles of ``z^2 + d1 z + d2`` (``s = log(z) / dt``), then the delay in
    ``[m dt, (m + 1) dt]`` and ``a`` (linear, closed form) that fit best: ``(cost, q)``."""
    z = np.roots([1.0, d1, d2]).astype(complex)
    if np.any(np.abs(z) == 0) or not np.all(np.isfinite(z)):
        return None
    s = np.log(z) / dt
    b, c = max(float(-np.real(s[0] + s[1])), 0.0), max(float(np.real(s[0] * s[1])), 0.0)
    best = None
    hold = 0.5 * dt if T == 0 else 0.0  # a continuous fit lumps the hold into the delay
    for e in np.linspace(0.0, 1.0, 11):
        tau = (m + e) * dt + hold
        try:
            G = plant_response(f, 1.0, b, c, tau, T)
        except (InvalidInputError, SimulationError, ValueError):
            return None
        wg = G / sd
        den = float(np.sum(np.abs(wg) ** 2))
        if not np.isfinite(den) or den <= 0:
            continue
        a = float(np.real(np.sum(np.conj(wg) * H / sd))) / den
        if not a > 0:
            continue
        cost = float(np.sum(np.abs((a * G - H) / sd) ** 2))
        if best is None or cost < best[0]:
            best = (cost, np.array([np.log(a), b, c, tau]))
    return best


def _fit_plant_delay_span(f: NDArray[np.float64], H: NDArray[np.complex128], sd: NDArray[np.float64], T: float, fit_delay: bool, delay: float,
                          max_delay: float, extra: list[tuple[float, NDArray[np.float64]]] | None = None,
                          bound: float | None = None, period: float | None = None) -> tuple[NDArray[np.float64], Any]:
    """The NLS from the best Levy starts on a grid of delays in ``[0, max_delay]`` and from the
    sampled search's starts ``extra``; the delay bounded by ``bound`` (default
    ``1.5 max_delay``)."""
    wrel = np.abs(H) / sd  # 1 / relative standard deviation
    H_levy = H / zoh_factor(f, T)

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        tau = q[3] if fit_delay else delay
        try:
            e = (plant_response(f, float(np.exp(q[0])), float(q[1]), float(q[2]), float(tau), T) - H) / sd
        except (InvalidInputError, SimulationError, OverflowError):
            # a trial plant too fast for the step (or overflowing): far from the data
            return np.full(2 * f.size, 1e6)
        return np.concatenate([e.real, e.imag])

    # 80 starts per period of the highest bin: the cost has a local minimum every period
    n_taus = int(np.clip(round(80 * max_delay * f.max()) + 1, 161, 4001))
    taus = np.linspace(0.0, max_delay, n_taus) if fit_delay else np.array([delay])
    starts = []
    for tau in taus:
        sol = _levy(f, H_levy, wrel, tau)
        if sol is None or sol[0] <= 0:
            continue
        q = np.array([np.log(sol[0]), max(sol[1], 0.0), max(sol[2], 0.0), tau])
        starts.append((float(np.sum(resid(q) ** 2)), q))
    if not starts:
        # fall back on a rigid-body guess from the high-frequency magnitude
        a0 = float(np.median(np.abs(H) * (2 * np.pi * f) ** 2))
        starts = [(0.0, np.array([np.log(max(a0, 1e-300)), 2 * np.pi * f.min(), 0.0, delay]))]
    starts.sort(key=lambda s: s[0])
    extra = sorted(extra or [], key=lambda s: s[0])
    lo = np.array([-np.inf, 0.0, 0.0, 0.0])
    hi = np.array([np.inf, np.inf, np.inf, max(1.5 * max_delay if bound is None else bound, 1e-12)])
    best = None
    runs = []
    # the best continuous starts and the best sampled ones (either kind can mislead the other's ranking)
    for j, (_, q0) in enumerate(starts[:3] + extra[:3]):
        q0 = np.clip(q0, lo, hi * (1 - 1e-9))
        if not fit_delay:
            q0[3] = 0.0
        # a sampled start near its optimum converges in tens of steps; one that crawls is not it
        r = least_squares(resid, q0, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=2000 if j < len(starts[:3]) else 300)
        runs.append(r)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    best.bounds_hi = hi
    best.others = [r.x for r in runs if r is not best]
    best.direct_chi2 = lambda q: float(np.sum(resid(q) ** 2))
    if fit_delay:
        cands = best.others + _period_shifts(best.x, period, float(hi[3]))
        best.alternatives = [(float(q[3]), float(np.sum(resid(q) ** 2)) - 2.0 * best.cost) for q in cands]
    return best.x, best


def _period_shifts(q: NDArray[np.float64], period: float | None, bound: float, n_max: int = 4) -> list[NDArray[np.float64]]:
    """``q`` with its delay shifted by whole excitation periods (the nearest ``n_max`` on each
    side) within ``[0, bound]``: a periodic excitation's lines cannot tell these delays apart."""
    if not period or period <= 0:
        return []
    out = []
    for j in range(1, n_max + 1):
        for sign in (-1, 1):
            tau = q[3] + sign * j * period
            if 0.0 <= tau <= bound:
                qj = q.copy()
                qj[3] = tau
                out.append(qj)
    return out


def plant_to_control(result: IdentificationResult, pade_order: int | None = None) -> Any:
    """The identified plant as a python-control ``TransferFunction``; the delay is kept as the
    attribute ``delay`` or, with ``pade_order``, multiplied in as a Pade approximation."""
    import control  # type: ignore[import-not-found]

    a, b, c, tau = (result.value(k) for k in PLANT_NAMES)
    tf = control.tf([a], [1.0, b, c])
    if pade_order:
        num, den = control.pade(tau, pade_order)
        tf = tf * control.tf(num, den)
    else:
        tf.delay = tau
    return tf
