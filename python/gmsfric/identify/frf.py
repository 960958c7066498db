"""Frequency response from band-limited random excitation, and the plant fit of paper eq. 1.

``H1 = S_uy / S_uu`` (scipy.signal.csd / welch, Hann windows, 50 % overlap) with the coherence
``gamma^2``.  With feedback, pass the external ``excitation`` r: ``H = S_ry / S_ru`` (the
joint input-output estimate), unbiased by measurement noise fed back through the controller.

:func:`fit_plant` fits ``a / (s^2 + b s + c) exp(-s delay)`` by frequency-domain nonlinear least
squares.  Each bin's complex error is divided by the standard deviation of the H1 estimate,
``|H| sqrt((1 - gamma^2) / (2 n_avg gamma^2))`` (Bendat & Piersol), so coherence weights the
fit and the residuals are ~unit variance.  Start values need not be given: a linear
(Levy) least-squares fit of ``H (s^2 + b s + c) = a exp(-s tau)`` is solved on a grid of delays and
the best one starts the nonlinear fit.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import signal
from scipy.optimize import least_squares

from .. import units as _units
from .._validate import as_array, positive, same_length
from ..errors import IdentificationError, InvalidInputError
from ..system import Plant
from .results import IdentificationResult, covariance_from_jacobian, transform_covariance

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

    def select(self, fmin: float = 0.0, fmax: float = np.inf) -> "FRF":
        """The bins with ``fmin <= f <= fmax``."""
        m = (self.f >= fmin) & (self.f <= fmax)
        return FRF(self.f[m], self.H[m], self.coherence[m], self.n_averages, self.dt, self.bin_correlation)

    @property
    def stderr(self) -> NDArray[np.float64]:
        """Standard deviation of each complex bin, ``|H| sqrt((1-g^2)/(2 n g^2))``."""
        g = np.clip(self.coherence, 1e-6, COHERENCE_CAP)
        return np.abs(self.H) * np.sqrt((1 - g) / (2 * self.n_averages * g))

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
    u = as_array("input", u, min_len=64)
    y = as_array("output", y)
    same_length("output", y, "input", u.size)
    if np.isscalar(t):
        fs = positive("sample_rate", float(t))  # type: ignore[arg-type]
    else:
        tt = as_array("time", t)
        same_length("time", tt, "input", u.size)
        d = np.diff(tt)
        if np.any(d <= 0):
            raise InvalidInputError("`time` must increase strictly")
        if np.ptp(d) > 1e-3 * np.median(d):
            raise InvalidInputError("`time` must be uniformly sampled for the FRF (resample first)")
        fs = 1.0 / float(np.mean(d))
    n = u.size
    if nperseg is None:
        nperseg = int(2 ** np.floor(np.log2(max(n / 16, 32))))
    nperseg = int(min(nperseg, n))
    if np.ptp(u) == 0:
        raise IdentificationError("the input is constant: no excitation to estimate a frequency response from")
    ref = u if excitation is None else as_array("excitation", excitation)
    same_length("excitation", ref, "input", n)
    kw = dict(fs=fs, nperseg=nperseg, detrend=detrend, window="hann")
    f, p_rr = signal.welch(ref, **kw)
    _, p_yy = signal.welch(y, **kw)
    _, p_ry = signal.csd(ref, y, **kw)
    if excitation is None:
        H = p_ry / p_rr
    else:
        _, p_ru = signal.csd(ref, u, **kw)
        H = p_ry / p_ru
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.nan_to_num(np.abs(p_ry) ** 2 / (p_rr * p_yy), nan=0.0)
    n_avg = max(1, int((n - nperseg) // (nperseg // 2) + 1))
    m = f > 0
    win = signal.get_window("hann", nperseg)
    w2 = win**2
    k = np.arange(nperseg)
    rho = [abs(np.sum(w2 * np.exp(-2j * np.pi * j * k / nperseg))) / np.sum(w2) for j in range(1, 4)]
    return FRF(f[m], H[m], np.clip(coh[m], 0.0, 1.0), n_avg, 1.0 / fs, 1.0 + 2.0 * float(np.sum(np.square(rho))))


def zoh_factor(f: NDArray[np.float64], dt: float) -> NDArray[np.complex128]:
    """Zero-order hold ``(1 - exp(-s dt)) / (s dt)`` at ``s = 2 pi i f`` (1 for ``dt = 0``)."""
    if dt <= 0:
        return np.ones_like(f, dtype=complex)
    s = 2j * np.pi * f
    return (1 - np.exp(-s * dt)) / (s * dt)


def plant_response(f: NDArray[np.float64], a: float, b: float, c: float, delay: float, dt: float = 0.0) -> NDArray[np.complex128]:
    """``a / (s^2 + b s + c) exp(-s delay)`` at ``s = 2 pi i f``, times the zero-order hold of
    period ``dt`` when ``dt > 0``."""
    s = 2j * np.pi * f
    return a / (s * s + b * s + c) * np.exp(-s * delay) * zoh_factor(f, dt)


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
        From :func:`estimate_frf`.
    fmin, fmax : float
        Frequency band of the fit.
    min_coherence : float
        Bins below this coherence are left out.
    max_delay : float, optional
        Upper end of the delay search; default one period of the highest fitted frequency.
    fit_delay : bool
        Fit the delay (else hold it at ``delay``).
    force_gain : float, optional
        Force per drive-input unit (the motor constant), in ``force_gain_unit``: not identifiable
        from an FRF, carried into the returned :class:`~gmsfric.system.Plant` and the JSON.
        Without it the ``model_object`` carries 1 (so friction would enter unscaled) and the
        JSON's model document states no force gain, so it cannot be loaded as a Plant.
    zoh : bool
        Model the zero-order hold of the sampled drive (``(1 - e^{-sT})/(sT)``, about ``T/2`` of
        extra delay), so ``delay`` is the plant's own; ``False`` lumps the hold into ``delay``
        (as a plain continuous fit of the paper's kind would).
    time_unit, input_unit, output_unit : str
        Units of the data (any :mod:`gmsfric.units` reads); the parameters are reported in
        them, ``model_object`` is converted to SI.
    force_gain_unit : str, optional
        Unit of ``force_gain``; default ``N/<input_unit>`` (``N m/<input_unit>`` when the output
        is an angle).

    Returns
    -------
    IdentificationResult
        ``model="plant"``, parameters ``a b c delay``; ``model_object`` is a ``Plant`` in SI (when
        the estimates are admissible).

    Raises
    ------
    UnitError
        A unit unknown or not of its quantity (before any work).
    """
    units, force_gain_unit = plant_units(time_unit, input_unit, output_unit, force_gain_unit)
    if force_gain is not None:
        force_gain = positive("force_gain", force_gain)
    sel = frf.select(fmin, fmax)
    m = sel.coherence >= min_coherence
    f, H, g = sel.f[m], sel.H[m], sel.coherence[m]
    if f.size < 8:
        raise IdentificationError(f"only {f.size} frequency bins with coherence >= {min_coherence} in the band: need at least 8 (more excitation or a longer record)")
    sd = FRF(f, H, g, sel.n_averages).stderr
    wrel = np.abs(H) / np.maximum(sd, 1e-300)  # 1 / relative standard deviation
    if max_delay is None:
        max_delay = 1.0 / f.max()

    T = sel.dt if zoh else 0.0
    H_levy = H / zoh_factor(f, T)

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        a, b, c = np.exp(q[0]), q[1], q[2]
        tau = q[3] if fit_delay else delay
        e = (plant_response(f, a, b, c, tau, T) - H) / sd
        return np.concatenate([e.real, e.imag])

    taus = np.linspace(0.0, max_delay, 81) if fit_delay else np.array([delay])
    starts = []
    for tau in taus:
        sol = _levy(f, H_levy, wrel, tau)
        if sol is None or sol[0] <= 0:
            continue
        q = np.array([np.log(sol[0]), max(sol[1], 0.0), max(sol[2], 0.0), tau])
        starts.append((float(np.sum(resid(q) ** 2)), q))
    if not starts:
        # fall back on a rigid-body guess from the high-frequency magnitude
        w2 = (2 * np.pi * f) ** 2
        a0 = float(np.median(np.abs(H) * w2))
        starts = [(0.0, np.array([np.log(max(a0, 1e-300)), 2 * np.pi * f.min(), 0.0, 0.0]))]
    starts.sort(key=lambda s: s[0])
    lo = np.array([-np.inf, 0.0, 0.0, 0.0])
    hi = np.array([np.inf, np.inf, np.inf, max(max_delay * 2, 1e-12)])
    best = None
    for _, q0 in starts[:3]:
        q0 = np.clip(q0, lo, hi * (1 - 1e-9))
        if not fit_delay:
            q0[3] = 0.0
        r = least_squares(resid, q0, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=2000)
        if best is None or r.cost < best.cost:
            best = r
    assert best is not None
    q = best.x
    jac = best.jac if fit_delay else best.jac[:, :3]
    cov = covariance_from_jacobian(jac, best.fun) * frf.bin_correlation
    se = np.sqrt(np.clip(np.diag(cov), 0, np.inf))
    a = float(np.exp(q[0]))
    tau = float(q[3]) if fit_delay else float(delay)
    params = {
        "a": (a, a * se[0]),
        "b": (float(q[1]), float(se[1])),
        "c": (float(q[2]), float(se[2])),
        "delay": (tau, float(se[3]) if fit_delay else 0.0),
    }
    dof = max(2 * f.size - 4, 1)
    info = {"zoh_dt": T, "n_bins": int(f.size), "band": [float(f.min()), float(f.max())], "chi2_per_dof": float(2 * best.cost / dof), "n_averages": frf.n_averages}
    info["force_gain"] = force_gain
    if force_gain is not None:
        units["force_gain"] = force_gain_unit
    plant = None
    try:
        plant = plant_si({"a": a, "b": params["b"][0], "c": params["c"][0], "delay": tau, "force_gain": 1.0 if force_gain is None else force_gain},
                         {**units, "force_gain": "N/V" if force_gain is None else force_gain_unit})
    except InvalidInputError:  # pragma: no cover
        pass
    # covariance of (a, b, c, delay) from that of (log a, b, c[, delay]); a held delay has none
    jac_p = np.eye(4)[:, : cov.shape[0]] * np.array([a, 1.0, 1.0, 1.0])[:, None]
    cov_p = transform_covariance(cov, jac_p)
    return IdentificationResult("plant", params, units, info, data={"frf": frf, "fit_f": f, "input_unit": input_unit, "output_unit": output_unit},
                                model_object=plant, covariance=(list(PLANT_NAMES), cov_p))


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
