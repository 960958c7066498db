"""Random identification experiments with known truths (SI inside), written as measurement files.

Every case is drawn from its own ``numpy.random.SeedSequence((seed, family, index))``, so a case
does not depend on which other cases run or in what order.  Families:

========================  ====================================================================
``static-points``         steady (v, F) points, both directions, log-spaced speeds, white noise
``static-raw``            raw closed-loop constant-velocity run (mass + eq. 2 + PID), 0.5-5 kHz
``presliding-virgin``     1..8 Maxwell-slip blocks, break displacements over up to 3 decades,
                          0.1 Hz sine: small then large amplitude (breaks every block), 5 nm
``presliding-hyst``       the same blocks, random reversal amplitudes from a non-virgin state
``presliding-issue``      4..6 blocks over 1.5 decades (well under 1 um to ~20 um), virgin test
``plant-open``            ``a/(s^2+bs+c) e^{-s tau}``, band-limited random drive, 0.5-10 kHz
``plant-closed``          the same plant under PID, excitation at the drive or the reference
========================  ====================================================================

Files are CSV with a header row; :func:`write_case` writes a case in SI or in the family's other
units (mm, um, mN, mV, ms) and returns the column names and the units used.
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import butter, sosfilt

import sims

FAMILIES = ("static-points", "static-raw", "presliding-virgin", "presliding-hyst", "presliding-issue", "plant-open", "plant-closed")
IDENTIFIER = {f: f.split("-")[0] for f in FAMILIES}

# scale of each unit to SI; the campaign writes files in these and parses the JSON's unit strings
UNIT_SCALE = {
    "m": 1.0, "mm": 1e-3, "um": 1e-6, "µm": 1e-6, "nm": 1e-9,
    "N": 1.0, "mN": 1e-3, "kN": 1e3,
    "s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0,
    "V": 1.0, "mV": 1e-3,
    "1": 1.0, "rad": 1.0,
}


@dataclass
class Case:
    """One experiment: the truth (SI), the recorded columns (SI) and what the run needs."""

    family: str
    index: int
    seed: int
    truth: dict[str, float]
    columns: dict[str, np.ndarray]
    roles: dict[str, str]            # column name -> quantity ("time", "position", "force", ...)
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def id(self) -> str:
        return f"{self.family}-{self.index:04d}"

    @property
    def identifier(self) -> str:
        return IDENTIFIER[self.family]


def _rng(seed: int, family: str, index: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence((seed, zlib.crc32(family.encode()), index)))


def _logu(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


# --------------------------------------------------------------------------- pre-sliding

ENCODER_PRESLIDING = 5e-9


def draw_blocks(rng: np.random.Generator, n: int, span: float, d_max: float, min_gap: float = 0.12) -> tuple[np.ndarray, np.ndarray]:
    """``n`` blocks whose break displacements span ``span`` decades up to ``d_max`` (m), adjacent
    ones at least ``min_gap`` decades apart; break forces of comparable size (0.25..1 ratio)."""
    if n == 1:
        logd = np.array([0.0])
    else:
        gaps = min_gap + (span - (n - 1) * min_gap) * rng.dirichlet(np.ones(n - 1))
        logd = np.concatenate([[0.0], np.cumsum(gaps)]) - span
    d = d_max * 10.0 ** logd
    frac = np.exp(rng.uniform(math.log(0.25), 0.0, n))
    w = frac / frac.sum() * _logu(rng, 0.05, 5.0)
    return w / d, w


def _block_truth(k: np.ndarray, w: np.ndarray) -> dict[str, float]:
    out = {}
    for i, (ki, wi) in enumerate(zip(k, w)):
        out[f"k{i + 1}"] = float(ki)
        out[f"w{i + 1}"] = float(wi)
    return out


def _presliding_record(rng: np.random.Generator, k: np.ndarray, w: np.ndarray, x_of_t, duration: float, rate: float,
                       z0: np.ndarray | None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    over = 8  # the blocks see an 8x finer path, so reversals between samples are resolved
    n = int(round(duration * rate))
    tf = np.arange(n * over) / (rate * over)
    xf = x_of_t(tf)
    Ff = sims.maxwell_slip_force(xf, k, w, z0)
    t, x, F = tf[::over], xf[::over], Ff[::over]
    noise = float(np.sum(w)) * rng.uniform(0.001, 0.004)
    xm = ENCODER_PRESLIDING * np.round(x / ENCODER_PRESLIDING)
    Fm = F + noise * rng.standard_normal(n)
    return {"t": t, "x": xm, "F": Fm}, {"force_noise": noise, "encoder": ENCODER_PRESLIDING, "rate": rate, "samples": n}


def make_presliding(family: str, index: int, seed: int, small: bool = False) -> Case:
    rng = _rng(seed, family, index)
    if family == "presliding-issue":
        n = int(rng.integers(4, 7))
        d_max = rng.uniform(15e-6, 25e-6)
        span = 1.5
        k, w = draw_blocks(rng, n, span, d_max, min_gap=0.15)
    else:
        n = int(rng.integers(1, 9))
        span = 0.0 if n == 1 else rng.uniform(max(0.4, (n - 1) * 0.12 + 0.15), 3.0)
        # smallest break displacement >= 50 nm (10 encoder counts), largest <= 50 um
        d_min = _logu(rng, 50e-9, max(50e-9, min(2e-6, 50e-6 / 10.0**span)))
        k, w = draw_blocks(rng, n, span, d_min * 10.0**span)
    d = w / k
    rate = 200.0 if small else float(rng.choice([200.0, 500.0]))
    meta: dict[str, Any] = {"n_blocks": n, "span_decades": float(np.log10(d.max() / d.min())), "d_min": float(d.min()), "d_max": float(d.max())}
    if family in ("presliding-virgin", "presliding-issue"):
        freq, cycles = 0.1, (1 if small else 2)
        a_large = d.max() * rng.uniform(1.3, 2.0)
        a_small = _logu(rng, min(2 * d.min(), a_large / 4), max(2 * d.min(), a_large / 4)) if n > 1 else a_large / 3
        amps = [a_small, a_large]
        cols, m2 = _presliding_record(rng, k, w, lambda t: sims.virgin_sine_position(t, amps, freq, cycles), len(amps) * cycles / freq, rate, None)
        # first maximum of the large sine: every block saturated forwards (for reference.py)
        meta.update(test="virgin", amplitudes=amps, frequency=freq, saturated_index=int(np.floor((cycles + 0.25) / freq * rate)), saturated_sign=1.0)
    else:
        n_moves = 10 if small else 18
        swing = np.exp(rng.uniform(np.log(d.min()), np.log(3.5 * d.max()), n_moves))
        big = rng.random(n_moves) < 0.3
        big[rng.integers(1, n_moves)] = True  # at least one swing past the last break after the start
        swing[big] = rng.uniform(2.4, 3.5, big.sum()) * d.max()
        turns = np.concatenate([[0.0], np.cumsum(swing * np.where(np.arange(n_moves) % 2 == 0, 1.0, -1.0))])
        durations = rng.uniform(2.0, 6.0, n_moves)
        z0 = d * rng.uniform(-1.0, 1.0, n)  # a history before the record: no virgin branch
        cols, m2 = _presliding_record(rng, k, w, lambda t: sims.reversal_position(t, turns, durations), float(durations.sum()) + 0.5, rate, z0)
        j = int(np.argmax(swing > 2.05 * d.max()))  # the first move that saturates every block
        meta.update(test="hysteresis", reversals=n_moves, saturated_index=int(np.floor(durations[: j + 1].sum() * rate)),
                    saturated_sign=1.0 if j % 2 == 0 else -1.0)
    meta.update(m2)
    return Case(family, index, seed, _block_truth(k, w), cols, {"t": "time", "x": "position", "F": "force"}, meta)


# --------------------------------------------------------------------------- static map

def _draw_static(rng: np.random.Generator) -> tuple[dict[str, float], np.ndarray]:
    vs = _logu(rng, 0.5e-3, 3e-3)
    fc = _logu(rng, 0.5, 20.0)
    fs = fc * rng.uniform(1.15, 2.0)
    delta = rng.uniform(0.5, 2.5)
    n_speeds = int(rng.integers(8, 15))
    v_lo, v_hi = vs * rng.uniform(0.1, 0.4), vs * rng.uniform(30.0, 100.0)
    speeds = np.geomspace(v_lo, v_hi, n_speeds)
    sigma = rng.uniform(0.2, 1.5) * fc / v_hi
    return {"fc": fc, "fs": fs, "vs": vs, "sigma": sigma, "delta": delta}, speeds


def make_static_points(family: str, index: int, seed: int, small: bool = False) -> Case:
    rng = _rng(seed, family, index)
    truth, speeds = _draw_static(rng)
    v = np.concatenate([speeds, -speeds])
    noise = truth["fc"] * rng.uniform(0.003, 0.015)
    F = sims.stribeck_force(v, **truth) + noise * rng.standard_normal(v.size)
    return Case(family, index, seed, truth, {"v": v, "F": F}, {"v": "velocity", "F": "force"}, {"force_noise": noise, "n_points": int(v.size)})


def _negative_slope(truth: dict[str, float], v_lo: float) -> float:
    """Largest ``-dF/dv`` of eq. 2 for ``v >= v_lo`` (the loop must damp it to avoid stick-slip)."""
    v = np.geomspace(v_lo, 1e3 * truth["vs"], 2000)
    F = sims.stribeck_force(v, **truth)
    return float(max(0.0, -np.min(np.diff(F) / np.diff(v))))


def make_static_raw(family: str, index: int, seed: int, small: bool = False) -> Case:
    rng = _rng(seed, family, index)
    truth, speeds = _draw_static(rng)
    if small:
        speeds = np.geomspace(speeds[0], speeds[-1], 7)
    rate = 1000.0 if small else _logu(rng, 500.0, 5000.0)
    T = 1.0 / rate
    q = _logu(rng, 10e-9, 0.5e-6)
    hold = np.clip(5e-3 / speeds, 1.0, 1.5 if small else 3.0)
    _, vref, plateaus = sims.velocity_profile(speeds, hold, accel=speeds[-1] / 0.1, dwell=0.3, T=T)
    xref = np.concatenate([[0.0], np.cumsum(0.5 * (vref[1:] + vref[:-1]) * T)])
    omega = 2 * np.pi * min(rng.uniform(10.0, 30.0), rate / 40.0)
    slope = _negative_slope(truth, speeds[0] / 2)
    m = max(_logu(rng, 1.0, 10.0), 1.2 * slope / (0.9 * omega))
    kp, kd, ki = m * omega**2, 1.8 * m * omega, m * omega**3 / 5.0
    dist_rms = truth["fc"] * rng.uniform(0.002, 0.01)
    dist = dist_rms * rng.standard_normal(vref.size)
    nsub = max(1, int(math.ceil(T / 20e-6)))
    pos, cmd, vel = sims.simulate_velocity_run(xref, vref, dist, q=q, T=T, nsub=nsub, m=m, kp=kp, ki=ki, kd=kd, tf=1.0 / (5 * omega), **truth)
    f_noise = truth["fc"] * rng.uniform(0.002, 0.01)
    force = cmd + f_noise * rng.standard_normal(cmd.size)
    t = np.arange(vref.size) * T
    # how steady the true motion is on the last 3/4 of each plateau (a check of the simulator)
    steady = []
    for t0, t1, v in plateaus:
        s = (t >= t0 + 0.25 * (t1 - t0)) & (t < t1)
        steady.append(float(np.std(vel[s]) / abs(v)))
    meta = {"rate": rate, "encoder": q, "mass": m, "bandwidth_hz": omega / (2 * np.pi), "n_speeds": int(speeds.size), "v_min": float(speeds[0]),
            "v_max": float(speeds[-1]), "force_noise": f_noise, "disturbance": dist_rms, "samples": int(t.size),
            "worst_plateau_velocity_cv": float(max(steady))}
    return Case(family, index, seed, truth, {"t": t, "x": pos, "F": force}, {"t": "time", "x": "position", "F": "force"}, meta)


# --------------------------------------------------------------------------- plant

def _band_noise(rng: np.random.Generator, n: int, rate: float, f_lo: float, f_hi: float) -> np.ndarray:
    sos = butter(4, [f_lo, f_hi], btype="bandpass", fs=rate, output="sos")
    e = sosfilt(sos, rng.standard_normal(n + 2000))[2000:]
    return e / e.std()


def _draw_plant(rng: np.random.Generator, small: bool) -> tuple[dict[str, float], float, int]:
    rate = 2000.0 if small else float(rng.choice([500.0, 1000.0, 2000.0, 5000.0, 10000.0]))
    fn = _logu(rng, 0.3, 30.0)
    zeta = _logu(rng, 0.1, 10.0)
    wn = 2 * np.pi * fn
    truth = {"a": _logu(rng, 0.005, 0.5), "b": 2 * zeta * wn, "c": wn**2, "delay": rng.uniform(0.2e-3, 3e-3)}
    n = int(min(rng.uniform(20.0, 40.0) * rate, 2**18)) if not small else 16384
    return truth, rate, n


def make_plant_open(family: str, index: int, seed: int, small: bool = False) -> Case:
    rng = _rng(seed, family, index)
    truth, rate, n = _draw_plant(rng, small)
    T = 1.0 / rate
    f_hi = min(0.35 * rate, rng.uniform(100.0, 400.0))
    u = _band_noise(rng, n, rate, 0.5, f_hi)
    y = sims.simulate_plant_open(u, truth["a"], truth["b"], truth["c"], truth["delay"], T)
    q = _logu(rng, 10e-9, 1e-6)
    ym = q * np.round((y + 0.3 * q * rng.standard_normal(n)) / q)
    meta = {"rate": rate, "encoder": q, "band_hz": [0.5, f_hi], "samples": n, "delay_samples": truth["delay"] * rate}
    return Case(family, index, seed, truth, {"t": np.arange(n) * T, "u": u, "y": ym}, {"t": "time", "u": "input", "y": "output"}, meta)


def make_plant_closed(family: str, index: int, seed: int, small: bool = False) -> Case:
    rng = _rng(seed, family, index)
    truth, rate, n = _draw_plant(rng, small)
    T = 1.0 / rate
    a, b, c, tau = truth["a"], truth["b"], truth["c"], truth["delay"]
    q = _logu(rng, 10e-9, 1e-6)
    f_hi = min(0.35 * rate, rng.uniform(100.0, 400.0))
    exc = _band_noise(rng, n, rate, 0.5, f_hi)
    noise = 0.3 * q * rng.standard_normal(n)
    at_reference = bool(rng.random() < 0.5)
    wc = min(2 * np.pi * rng.uniform(5.0, 40.0), 0.3 / (tau + T / 2), 2 * np.pi * rate / 20)
    for _ in range(8):
        s = 1j * wc
        P = a / (s * s + b * s + c)
        # PD zero at wc/3 and unit loop gain at wc (phase margin ~70 deg less the delay), then I
        kd = 1.0 / (abs(P) * wc * math.sqrt(1 + 1 / 9))
        kp, ki = kd * wc / 3, kd * wc**2 / 30
        if at_reference:
            ref, rin = exc * q * rng.uniform(300.0, 3000.0), np.zeros(n)
        else:
            ref, rin = np.zeros(n), exc * rng.uniform(0.2, 2.0) * kp * q * 1000
        y, u = sims.simulate_plant_pid(ref, rin, noise, a=a, b=b, c=c, tau=tau, T=T, q=q, kp=kp, ki=ki, kd=kd, tf=1.0 / (5 * wc))
        if np.all(np.isfinite(y)) and np.std(y[-n // 4:]) < 5 * np.std(y[n // 4: n // 2]) + 10 * q:
            break
        wc *= 0.6
    else:  # pragma: no cover
        raise RuntimeError(f"{family} {index}: no stabilising PID found")
    meta = {"rate": rate, "encoder": q, "band_hz": [0.5, f_hi], "samples": n, "delay_samples": tau * rate, "crossover_hz": wc / (2 * np.pi),
            "excitation_at": "reference" if at_reference else "drive", "pid": [kp, ki, kd]}
    r = ref if at_reference else rin
    return Case(family, index, seed, truth, {"t": np.arange(n) * T, "u": u, "y": y, "r": r},
                {"t": "time", "u": "input", "y": "output", "r": "excitation_ref" if at_reference else "input"}, meta)


MAKERS = {
    "static-points": make_static_points,
    "static-raw": make_static_raw,
    "presliding-virgin": make_presliding,
    "presliding-hyst": make_presliding,
    "presliding-issue": make_presliding,
    "plant-open": make_plant_open,
    "plant-closed": make_plant_closed,
}


def make_case(family: str, index: int, seed: int, small: bool = False) -> Case:
    """The case ``index`` of ``family`` for campaign ``seed`` (``small``: a short record for CI)."""
    return MAKERS[family](family, index, seed, small)


# --------------------------------------------------------------------------- files and units

SI_UNITS = {"time": "s", "position": "m", "force": "N", "velocity": "m/s", "input": "V", "output": "m", "excitation_ref": "m"}
# the other units each family is written in (the unit-invariance subset)
ALT_UNITS = {
    "static": {"time": "ms", "position": "mm", "force": "mN", "velocity": "mm/s"},
    "presliding": {"time": "ms", "position": "um", "force": "mN"},
    "plant": {"time": "ms", "input": "mV", "output": "um", "excitation_ref": "um"},
}


def unit_scale(unit: str) -> float:
    """SI scale of a unit expression such as ``N/(mm/s)``, ``um/(mV ms^2)``, ``1/s^2``."""
    tokens = [tok for tok in _tokenize(unit)]
    pos = 0

    def factor() -> float:
        nonlocal pos
        tok = tokens[pos]
        pos += 1
        if tok == "(":
            val = expr()
            pos += 1  # ")"
        elif tok in UNIT_SCALE:
            val = UNIT_SCALE[tok]
        else:
            try:
                val = float(tok)
            except ValueError:
                raise KeyError(f"unknown unit {tok!r} in {unit!r}") from None
        if pos < len(tokens) and tokens[pos] == "^":
            val = val ** float(tokens[pos + 1])
            pos += 2
        return val

    def expr() -> float:
        nonlocal pos
        val = factor()
        while pos < len(tokens) and tokens[pos] != ")":
            if tokens[pos] == "/":
                pos += 1
                val /= factor()
            else:
                if tokens[pos] == "*":
                    pos += 1
                val *= factor()
        return val

    return expr()


def _tokenize(unit: str) -> list[str]:
    out, cur = [], ""
    for ch in unit.replace("·", "*").replace("**", "^"):
        if ch in "()/^* ":
            if cur:
                out.append(cur)
                cur = ""
            if ch != " ":
                out.append(ch)
        else:
            cur += ch
    if cur:
        out.append(cur)
    return out


def write_case(case: Case, directory: Path, units: dict[str, str] | None = None) -> tuple[Path, dict[str, str]]:
    """Write ``case`` as CSV in ``units`` (quantity -> unit; SI where not given).

    Returns the path and the unit of every quantity the file uses.  A velocity unit follows the
    position and time units for a raw run (``mm`` and ``s`` make ``mm/s``).
    """
    units = {**SI_UNITS, **(units or {})}
    directory.mkdir(parents=True, exist_ok=True)
    tag = "si" if all(units[q] == SI_UNITS[q] for q in case.roles.values() if q in SI_UNITS) else "alt"
    path = directory / f"{case.id}-{tag}.csv"
    names, cols = [], []
    for name, quantity in case.roles.items():
        names.append(name)
        cols.append(case.columns[name] / unit_scale(units[quantity]))
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(names), comments="", fmt="%.10g")
    used = {q: units[q] for q in case.roles.values()}
    return path, used
