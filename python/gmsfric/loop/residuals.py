"""Residual analysis: does the force residual of a model still depend on something?

Every test compares a statistic of the residual against the same statistic on circularly
shifted residuals (the shift keeps the residual's own autocorrelation and spectrum but breaks its
alignment with the variable), so "significant" means "more structure than noise with this
colour would show" whatever the sample rate or trajectory.

Variables (``Finding.variable``) and the effects they point at:

==================  ===========================================  ==============================
variable            statistic                                    suggests
==================  ===========================================  ==============================
``velocity``        binned mean of r against qd                  stribeck, asymmetric_friction
``position``        binned mean of r against q                   position_dependent_force
``position_odd``    binned mean of r sign(qd) against q          position_dependent_friction
``time``            binned mean of r sign(qd) against t          friction_drift, heating
``time_even``       binned mean of r against t                   (drift of a force, offset)
``acceleration``    binned mean of r against qdd                 compliance, inertia
``lag``             correlation of r with d(f_hat)/dt            input_delay
``frequency``       peak coherence of r with qdd                 compliance
``reversal``        r sign(qd) against log distance from the      presliding_hysteresis
                    last reversal
==================  ===========================================  ==============================
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import signal

from .effects import position_periodogram, position_profile
from .idim import Array, Signals

SUGGESTS = {
    "velocity": ["stribeck", "asymmetric_friction"],
    "position": ["position_dependent_force"],
    "position_odd": ["position_dependent_friction"],
    "time": ["friction_drift", "heating"],
    "time_even": ["friction_drift", "offset"],
    "acceleration": ["compliance"],
    "lag": ["input_delay"],
    "frequency": ["compliance"],
    "reversal": ["presliding_hysteresis"],
}


@dataclass
class Finding:
    """One residual test.

    Attributes
    ----------
    variable : str
        What the residual was tested against.
    statistic : float
        Fraction of the residual variance explained by the variable (binned tests), or the
        correlation / coherence.
    z : float
        Standard score of ``statistic`` against circularly shifted residuals.
    p : float
        Fraction of shifted residuals with a statistic at least as large.
    significant : bool
        ``p`` below the smallest attainable value and ``z`` above the threshold.
    suggests : list of str
        Catalogue effects that could explain such structure.
    detail : dict
        Test-specific numbers (e.g. the dominant frequency or period).
    """

    variable: str
    statistic: float
    z: float
    p: float
    significant: bool
    suggests: list[str]
    detail: dict[str, float] = field(default_factory=dict)
    curve: dict[str, Any] = field(default_factory=dict, repr=False)

    def as_dict(self) -> dict[str, Any]:
        return {
            "variable": self.variable,
            "statistic": round(self.statistic, 6),
            "z": round(self.z, 2),
            "p": round(self.p, 4),
            "significant": self.significant,
            "suggests": self.suggests,
            **{k: (round(v, 6) if isinstance(v, float) else v) for k, v in self.detail.items()},
        }


def _bin_index(x: Array, nbins: int, log: bool = False) -> tuple[Array, Array]:
    edges = np.quantile(x, np.linspace(0, 1, nbins + 1))
    edges = np.unique(edges)
    i = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, max(edges.size - 2, 0))
    return i, edges


def _explained(i: Array, r: Array, nb: int) -> float:
    cnt = np.bincount(i, minlength=nb)
    tot = np.bincount(i, weights=r, minlength=nb)
    mu = np.where(cnt > 0, tot / np.maximum(cnt, 1), 0.0)
    rc = r - r.mean()
    return float((cnt * (mu - r.mean()) ** 2).sum() / max((rc**2).sum(), 1e-300))


def _shifts(n: int, n_null: int, rng: np.random.Generator) -> Array:
    return rng.integers(n // 10, n - n // 10, n_null) if n > 20 else np.arange(1, n)


def _score(stat: float, null: Array) -> tuple[float, float]:
    z = (stat - null.mean()) / (null.std() + 1e-300)
    p = (1 + np.sum(null >= stat)) / (1 + null.size)
    return float(z), float(p)


Z_THRESHOLD = 5.0


def binned_test(variable: str, x: Array, r: Array, *, nbins: int = 24, n_null: int = 99, rng: np.random.Generator, odd_sign: Array | None = None) -> Finding:
    """Explained variance of the residual by bins of ``x`` against circular-shift surrogates.

    With ``odd_sign`` the residual is multiplied by it (``sign(qd)``) first: structure that
    flips with the direction of motion.
    """
    y = r * odd_sign if odd_sign is not None else r
    i, edges = _bin_index(x, nbins)
    nb = max(edges.size - 1, 1)
    stat = _explained(i, y, nb)
    null = np.array([_explained(i, np.roll(y, s), nb) for s in _shifts(y.size, n_null, rng)])
    z, p = _score(stat, null)
    cnt = np.bincount(i, minlength=nb)
    mu = np.bincount(i, weights=y, minlength=nb) / np.maximum(cnt, 1)
    centres = np.array([x[i == k].mean() if cnt[k] else np.nan for k in range(nb)])
    return Finding(variable, stat, z, p, bool(p <= 1.0 / (1 + n_null) and z > Z_THRESHOLD), SUGGESTS[variable],
                   curve={"x": x, "y": y, "centres": centres, "means": mu, "null95": float(np.percentile(null, 95))})


def time_test(variable: str, t: Array, r: Array, chunk: int, *, odd_sign: Array | None = None, nblocks: int = 12) -> Finding:
    """Do the residual's means over ``nblocks`` stretches of time differ more than its short-term
    noise allows?  Short chunks (``chunk`` rows) estimate that noise; an F test compares the
    spread of block means with it.  (Circular shifts cannot serve as the null here: a slow
    component stays slow when shifted.)"""
    from scipy import stats

    y = r * odd_sign if odd_sign is not None else r
    m = y.size // chunk
    if m < 2 * nblocks:
        nblocks = max(2, m // 2)
    c = y[: m * chunk].reshape(m, chunk).mean(axis=1)
    k = m // nblocks
    c = c[: k * nblocks].reshape(nblocks, k)
    bm = c.mean(axis=1)
    within = float(((c - bm[:, None]) ** 2).sum() / max(nblocks * (k - 1), 1))
    F = float(k * bm.var(ddof=1) / max(within, 1e-300))
    p = float(stats.f.sf(F, nblocks - 1, nblocks * (k - 1)))
    z = float(stats.norm.isf(max(p, 1e-300)))
    expl = float(bm.var() / max(y.var(), 1e-300))
    tt = t[: m * chunk].reshape(m, chunk).mean(axis=1)[: k * nblocks].reshape(nblocks, k).mean(axis=1)
    return Finding(variable, expl, z, p, bool(z > Z_THRESHOLD and expl > 0.01), SUGGESTS[variable], {"F": F},
                   curve={"x": t, "y": y, "centres": tt, "means": bm, "null95": float("nan")})


def lag_test(s: Signals, r: Array, y_hat: Array, *, n_null: int = 99, rng: np.random.Generator) -> Finding:
    """Correlation of the residual with the rate of change of the predicted force (a delay
    ``tau`` leaves ``r ~ -tau df/dt``), and the lag maximising the cross-correlation of
    measured and predicted force."""
    dt_rows = s.dt * s.dec
    dy = np.gradient(y_hat, dt_rows)

    def corr(a: Array) -> float:
        return float(abs(np.corrcoef(a, dy)[0, 1]))

    stat = corr(r)
    null = np.array([corr(np.roll(r, k)) for k in _shifts(r.size, n_null, rng)])
    z, p = _score(stat, null)
    # least-squares delay estimate from r ~ -tau dy
    tau = float(-(r @ dy) / max(dy @ dy, 1e-300))
    lags = np.arange(-20, 21)
    f = s.y - s.y.mean()
    g = y_hat - y_hat.mean()
    xc = np.array([np.dot(np.roll(g, L), f) for L in lags]) / (np.linalg.norm(f) * np.linalg.norm(g))
    big = abs(tau) > 0.2 * s.dt  # a fifth of a sample: below that, timing is not the story
    return Finding("lag", stat, z, p, bool(p <= 1.0 / (1 + n_null) and z > Z_THRESHOLD and big), SUGGESTS["lag"],
                   {"delay_estimate_s": tau}, curve={"lags_s": lags * dt_rows, "xcorr": xc})


def coherence_test(s: Signals, r: Array, *, n_null: int = 29, rng: np.random.Generator) -> Finding:
    """Peak magnitude-squared coherence between residual and acceleration (a linear dynamic
    effect such as a resonance), against circular-shift surrogates."""
    fs = s.fs / s.dec
    nper = int(min(256, max(32, r.size // 8)))
    a = s.rows["qdd"]
    f, c = signal.coherence(r, a, fs=fs, nperseg=nper)
    band = (f > 0) & (f < 0.8 * fs / 2)
    stat = float(c[band].max()) if band.any() else 0.0
    fpk = float(f[band][np.argmax(c[band])]) if band.any() else float("nan")
    null = np.array([signal.coherence(np.roll(r, k), a, fs=fs, nperseg=nper)[1][band].max() for k in _shifts(r.size, n_null, rng)])
    z, p = _score(stat, null)
    fr, pr = signal.welch(r, fs=fs, nperseg=nper)
    return Finding("frequency", stat, z, p, bool(p <= 1.0 / (1 + n_null) and z > Z_THRESHOLD), SUGGESTS["frequency"],
                   {"peak_hz": fpk}, curve={"f": f, "coherence": c, "psd_f": fr, "psd": pr})


def reversal_distance(q: Array, qd: Array, v_eps: float) -> Array:
    """Distance travelled since the last reversal of motion, per sample."""
    out = np.empty_like(q)
    last_dir, q_rev = 0.0, q[0]
    for k in range(q.size):  # rows are decimated: cheap
        d = 0.0 if abs(qd[k]) < v_eps else np.sign(qd[k])
        if d != 0 and d != last_dir:
            q_rev, last_dir = q[k - 1] if k else q[k], d
        out[k] = abs(q[k] - q_rev)
    return out


def _attach_position_periodogram(f: "Finding", s: Signals, r: Array, *, odd: bool) -> None:
    """Add the position-domain periodogram of the residual profile (and its dominant period) to
    finding ``f``."""
    grid, prof = position_profile(s, r, odd=odd)
    if prof is not None:
        fr, pw = position_periodogram(grid, prof)
        f.curve.update(spatial_freq=fr, periodogram=pw)
        if fr.size:
            f.detail["dominant_period_m"] = float(1.0 / fr[np.argmax(pw)])


def analyse(s: Signals, r: Array, y_hat: Array, *, seed: int = 0, variables: list[str] | None = None) -> list[Finding]:
    """Run every residual test on decimated rows of one run.

    Parameters
    ----------
    s : Signals
        The preprocessed run.
    r : ndarray
        Residual ``y - y_hat`` on the rows of ``s``.
    y_hat : ndarray
        The model's prediction on the same rows.
    seed : int
        Seed of the circular-shift surrogates (results are reproducible).

    Returns
    -------
    list of Finding
    """
    rng = np.random.default_rng(seed)
    R = s.rows
    sg = np.sign(R["qd"])
    moving = np.abs(R["qd"]) > 0.05 * s.v_scale
    out: list[Finding] = []
    want = set(variables) if variables else set(SUGGESTS)
    if "velocity" in want:
        out.append(binned_test("velocity", R["qd"], r, rng=rng))
    if "position" in want:
        f = binned_test("position", R["q"], r, rng=rng)
        _attach_position_periodogram(f, s, r, odd=False)
        out.append(f)
    if "position_odd" in want and moving.sum() > 50:
        f = binned_test("position_odd", R["q"][moving], r[moving], rng=rng, odd_sign=sg[moving])
        _attach_position_periodogram(f, s, r, odd=True)
        out.append(f)
    chunk = max(5, int(round(0.25 / (s.dt * s.dec))))
    if "time" in want and moving.sum() > 50:
        out.append(time_test("time", R["t"][moving], r[moving], chunk, odd_sign=sg[moving]))
    if "time_even" in want:
        out.append(time_test("time_even", R["t"], r, chunk))
    if "acceleration" in want:
        out.append(binned_test("acceleration", R["qdd"], r, rng=rng))
    if "lag" in want:
        out.append(lag_test(s, r, y_hat, rng=rng))
    if "frequency" in want:
        out.append(coherence_test(s, r, rng=rng))
    if "reversal" in want and moving.sum() > 50:
        dist = reversal_distance(R["q"], R["qd"], 0.02 * s.v_scale)
        near = moving & (dist > 0)
        if near.sum() > 50:
            f = binned_test("reversal", np.log10(dist[near]), r[near], rng=rng, odd_sign=sg[near], nbins=16)
            out.append(f)
    return out
