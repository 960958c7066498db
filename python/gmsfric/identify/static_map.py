"""Static friction map (paper eq. 2) from constant-velocity tests.

``F(v) = sign(v) (fc + (fs - fc) exp(-|v/vs|^delta)) + sigma v``

Two entry points: :func:`fit_static_map` on a table of steady ``(velocity, force)`` points and
:func:`fit_static_map_from_run` on a raw closed-loop record ``(time, position, force)`` through
constant-velocity plateaus, which finds the plateaus itself (:func:`find_plateaus`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .. import curves
from .. import units as _units
from .._progress import Progress
from .._validate import as_array, positive, same_length
from ..errors import IdentificationError
from ..models import StaticFriction, Stribeck
from .results import IdentificationResult, covariance_from_jacobian, transform_covariance

NAMES = ("fc", "fs", "vs", "sigma", "delta")
MIN_POINTS = 6


def static_map_curve(v: ArrayLike, fc: float, fs: float, vs: float, sigma: float, delta: float) -> NDArray[np.float64]:
    """Paper eq. 2 evaluated at ``v`` (any consistent units), parameters in the fit's order
    (:func:`gmsfric.curves.static_map`)."""
    return curves.static_map(v, fc, fs, vs, delta, sigma)


#: Quantity of each parameter (for :mod:`gmsfric.units`).
QUANTITIES = {"fc": "force", "fs": "force", "vs": "velocity", "sigma": "damping", "delta": "dimensionless"}


def static_map_units(velocity_unit: str, force_unit: str) -> dict[str, str]:
    """Units of ``fc fs vs sigma delta`` for data in ``velocity_unit`` and ``force_unit``, after
    checking both (a rotary axis: ``rad/s`` with a torque ``N m``)."""
    rotary = _units.is_rotary(velocity_unit, "velocity", name="velocity_unit")
    _units.check(force_unit, "force", rotary=rotary, name="force_unit")
    return {"fc": force_unit, "fs": force_unit, "vs": velocity_unit, "sigma": _units.ratio(force_unit, velocity_unit), "delta": "1"}


def static_friction_si(values: dict[str, float], units: dict[str, str]) -> StaticFriction:
    """The :class:`~gmsfric.models.StaticFriction` of eq. 2 parameters given in ``units``, in SI."""
    si = {k: _units.to_si(values[k], units[k], QUANTITIES[k], name=f"units[{k!r}]") for k in NAMES}
    return StaticFriction(Stribeck(si["fc"], si["fs"], si["vs"], si["delta"]), sigma=si["sigma"])


# Internal parameter vector: (fc, fs, log vs, sigma, log delta)
def _to_params(q: NDArray[np.float64]) -> tuple[float, float, float, float, float]:
    return float(q[0]), float(q[1]), float(np.exp(q[2])), float(q[3]), float(np.exp(q[4]))


def _one_sided_fit(speed: NDArray[np.float64], force: NDArray[np.float64], weight: NDArray[np.float64], delta_bounds: tuple[float, float]) -> tuple[NDArray[np.float64], Any]:
    """Fit ``|F|`` against ``|v|`` (all speeds > 0); multi-start; returns the internal vector and
    the least_squares result."""

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return (static_map_curve(speed, *_to_params(q)) - force) * weight

    order = np.argsort(speed)
    s_sorted, f_sorted = speed[order], force[order]
    upper = s_sorted >= np.quantile(s_sorted, 0.5)
    if upper.sum() >= 2 and np.ptp(s_sorted[upper]) > 0:
        sig0, fc0 = np.polyfit(s_sorted[upper], f_sorted[upper], 1)
    else:
        sig0, fc0 = 0.0, float(np.median(f_sorted))
    sig0 = max(float(sig0), 0.0)
    fc0 = max(float(fc0), 1e-12 * max(np.abs(force).max(), 1e-300))
    fs0 = max(float(f_sorted[:max(1, len(f_sorted) // 8)].max()), fc0)
    scale = max(np.abs(force).max(), 1e-300)
    lo = np.array([0.0, 0.0, np.log(speed.min()) - 6.0, 0.0, np.log(delta_bounds[0])])
    hi = np.array([np.inf, np.inf, np.log(speed.max()) + 6.0, np.inf, np.log(delta_bounds[1])])
    best = None
    for vs0 in np.exp(np.linspace(np.log(speed.min()), np.log(speed.max()), 6)):
        for d0 in (0.7, 1.0, 2.0):
            d0 = float(np.clip(d0, *delta_bounds))
            q0 = np.array([fc0, fs0 + 1e-3 * scale, np.log(vs0), sig0, np.log(d0)])
            q0 = np.clip(q0, lo + 1e-9, hi - 1e-9)
            try:
                r = least_squares(resid, q0, bounds=(lo, hi), x_scale="jac", method="trf", max_nfev=400)
            except (ValueError, FloatingPointError):  # pragma: no cover
                continue
            if best is None or r.cost < best.cost:
                best = r
    if best is None:  # pragma: no cover
        raise IdentificationError("static map fit failed from every start value")
    return best.x, best


def _external(q: NDArray[np.float64], cov_q: NDArray[np.float64]) -> dict[str, tuple[float, float]]:
    fc, fs, vs, sigma, delta = _to_params(q)
    d = np.sqrt(np.clip(np.diag(cov_q), 0, np.inf))
    # delta method for the log-parametrised vs and delta
    se = (d[0], d[1], vs * d[2], d[3], delta * d[4])
    return dict(zip(NAMES, ((fc, se[0]), (fs, se[1]), (vs, se[2]), (sigma, se[3]), (delta, se[4]))))


def _fit_side(speed, force, weight, delta_bounds):  # type: ignore[no-untyped-def]
    q, r = _one_sided_fit(speed, force, weight, delta_bounds)
    cov = covariance_from_jacobian(r.jac, r.fun)
    return q, _external(q, cov), r


@dataclass
class Plateau:
    """One constant-velocity stretch found in a raw run."""

    start: int
    stop: int
    velocity: float
    force: float
    force_stderr: float
    kept_fraction: float
    dropped: str = ""


@dataclass
class PlateauSearch:
    plateaus: list[Plateau] = field(default_factory=list)
    rejected: list[Plateau] = field(default_factory=list)
    window: float = 0.0


def _adaptive_velocity(t: NDArray[np.float64], x: NDArray[np.float64], resolution: float, counts: float, max_h: int) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Velocity from the smallest centred difference ``x[k+h] - x[k-h]`` that spans at least
    ``counts`` position resolutions (so the relative precision is ~``1/counts`` at every speed);
    0 where even ``max_h`` does not (standstill).  Returns the velocity and the ``h`` used."""
    n = x.size
    idx = np.arange(n)
    v = np.zeros(n)
    used = np.zeros(n, dtype=np.int64)
    todo = np.ones(n, dtype=bool)
    h = 2
    while True:
        lo = np.clip(idx - h, 0, n - 1)
        hi = np.clip(idx + h, 0, n - 1)
        d = x[hi] - x[lo]
        hit = todo & (np.abs(d) >= counts * resolution) & (hi - lo == 2 * h)
        v[hit] = d[hit] / (t[hi[hit]] - t[lo[hit]])
        used[hit] = h
        todo &= ~hit
        if h >= max_h or not todo.any():
            break
        h = min(max_h, int(np.ceil(h * 1.5)))
    return v, used


def _split(v: NDArray[np.float64], a: int, b: int, tol_rel: float, min_len: int, out: list[tuple[int, int]]) -> None:
    """Binary segmentation of ``v[a:b]`` into stretches of nearly constant value."""
    seg = v[a:b]
    med = float(np.median(seg))
    q = min_len // 2
    core = seg[q : len(seg) - q] if len(seg) > 2 * q + 2 else seg
    if len(seg) <= 2 * min_len + 1 or np.abs(core - med).max() <= tol_rel * abs(med):
        out.append((a, b))
        return
    c = np.cumsum(seg)
    k = np.arange(min_len, len(seg) - min_len)
    left = c[k - 1] / k
    right = (c[-1] - c[k - 1]) / (len(seg) - k)
    stat = np.abs(left - right) * np.sqrt(k * (len(seg) - k) / len(seg))
    j = int(k[np.argmax(stat)])
    lm, rm = float(np.median(seg[:j])), float(np.median(seg[j:]))
    if abs(lm - rm) <= tol_rel * max(abs(lm), abs(rm)):
        out.append((a, b))
        return
    _split(v, a, a + j, tol_rel, min_len, out)
    _split(v, a + j, b, tol_rel, min_len, out)


def find_plateaus(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    counts: float = 30.0,
    max_window: float | None = None,
    settle: float = 0.25,
    rel_tol: float = 0.15,
    stick_slip_tol: float = 0.3,
    n_blocks: int = 8,
    min_travel: float | None = None,
    require_dissipative: bool = True,
) -> PlateauSearch:
    """Constant-velocity plateaus of a raw run, transients and stick-slip stretches dropped.

    Velocity is estimated by centred differences whose width adapts to the speed: the smallest
    that spans ``counts`` position resolutions (encoder quantum or noise level), so slow and fast
    plateaus are resolved alike.  Moving stretches of one sign are split where the velocity
    changes by more than ``rel_tol`` (binary segmentation), the first ``settle`` fraction of each
    is dropped as transient, and sub-blocks whose velocity is off by more than ``stick_slip_tol``
    are dropped as stick-slip.

    Parameters
    ----------
    t, position, force : array_like
        The record (any consistent units).
    counts : float
        Resolutions per velocity estimate (relative precision ~``1/counts``).
    max_window : float, optional
        Longest half-width (``t`` units) of the difference; slower motion is standstill.
        Default: 1/50 of the record.
    settle : float
        Fraction of each plateau dropped at its start as the transient (at least two windows).
    rel_tol : float
        Relative velocity change that starts a new plateau.
    stick_slip_tol : float
        Sub-blocks whose velocity deviates from the plateau's by more than this fraction are
        dropped (stick-slip, transients); plateaus keeping less than half are rejected.
    n_blocks : int
        Sub-blocks per plateau, also used for the standard error of the mean force
        (``std(block means) / sqrt(n)``).
    min_travel : float, optional
        Shortest distance travelled on a kept plateau; shorter ones (creep while settling) are
        rejected.  Default: ``2 * counts`` position resolutions.
    require_dissipative : bool
        Reject plateaus whose mean force does not have the sign of the velocity (pre-sliding or
        creep, not steady sliding).

    Returns
    -------
    PlateauSearch
        ``plateaus`` (kept) and ``rejected``.
    """
    t = as_array("time", t, min_len=10)
    x = as_array("position", position)
    f = as_array("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", f, "time", t.size)
    n = t.size
    dt = float(np.median(np.diff(t)))
    if max_window is None:
        max_window = (t[-1] - t[0]) / 50.0
    max_h = max(2, int(round(positive("max_window", max_window) / dt)))
    dx = np.abs(np.diff(x))
    quantum = float(dx[dx > 0].min()) if np.any(dx > 0) else 0.0
    # white position noise: robust scatter of second differences / sqrt(6)
    noise = 1.4826 * float(np.median(np.abs(np.diff(x, 2)))) / np.sqrt(6.0)
    resolution = max(quantum, noise, 1e-12 * max(np.abs(x).max(), 1e-300))
    if min_travel is None:
        min_travel = 2.0 * counts * resolution
    v, used = _adaptive_velocity(t, x, resolution, counts, max_h)
    sgn = np.sign(v)
    runs: list[tuple[int, int]] = []
    k = 0
    while k < n:
        if sgn[k] == 0:
            k += 1
            continue
        j = k
        while j < n and sgn[j] == sgn[k]:
            j += 1
        h_run = int(np.median(used[k:j]))
        if j - k >= 6 * h_run and j - k >= 3 * n_blocks:
            runs.append((k, j))
        k = j
    segments: list[tuple[int, int, int]] = []
    for a, b in runs:
        h_run = int(np.median(used[a:b]))
        parts: list[tuple[int, int]] = []
        _split(v, a, b, rel_tol, max(3 * h_run, n_blocks), parts)
        segments.extend((p0, p1, h_run) for p0, p1 in parts)
    out = PlateauSearch(window=float(np.median(used[used > 0]) * dt) if np.any(used > 0) else 0.0)
    for a, b, h in segments:
        a2 = a + max(2 * h, int(settle * (b - a)))
        b2 = b - h
        if b2 - a2 < max(n_blocks * 3, 2 * h):
            continue
        edges = np.linspace(a2, b2, n_blocks + 1).astype(int)
        vel_b = np.array([(x[e1 - 1] - x[e0]) / (t[e1 - 1] - t[e0]) for e0, e1 in zip(edges[:-1], edges[1:])])
        f_b = np.array([f[e0:e1].mean() for e0, e1 in zip(edges[:-1], edges[1:])])
        vel = float(np.polyfit(t[a2:b2] - t[a2], x[a2:b2], 1)[0])
        block_res = 2.0 * resolution / max(t[edges[1] - 1] - t[edges[0]], dt)
        ok = np.abs(vel_b - vel) <= stick_slip_tol * abs(vel) + block_res
        p = Plateau(int(a2), int(b2), vel, float(f_b[ok].mean()) if ok.any() else float("nan"), float("nan"), float(ok.mean()))
        if ok.sum() < max(2, n_blocks // 2 + 1) or vel == 0:
            p.dropped = "stick-slip or unsteady velocity"
            out.rejected.append(p)
            continue
        if quantum > 0:
            # stick-slip shows as standstills: encoder counts stop changing for much longer than
            # the quantum / speed expected on a steady plateau
            ch = np.flatnonzero(np.diff(x[a2:b2]) != 0)
            if ch.size > 2:
                gaps = np.diff(t[a2:b2][ch])
                expected = max(quantum / abs(vel), dt)
                stuck = float(gaps[gaps > 4.0 * expected].sum()) / max(float(t[b2 - 1] - t[a2]), dt)
                if stuck > 0.2:
                    p.dropped = f"stick-slip ({stuck:.0%} of the plateau at standstill)"
                    out.rejected.append(p)
                    continue
        # velocity oscillation (stick-slip without full stops, limit cycles): local velocity over
        # ~8 resolutions scatters far more than quantisation explains
        hl = max(1, int(np.ceil(8.0 * resolution / (abs(vel) * dt) / 2)))
        if b2 - a2 > 4 * hl:
            xs_ = x[a2:b2]
            v_loc = (xs_[2 * hl :] - xs_[: -2 * hl]) / (2 * hl * dt)
            cv = float(np.std(v_loc)) / abs(vel)
            expected_cv = resolution / (2 * hl * dt * abs(vel))
            # short-window roughness of the position about its local straight line
            L = max(10, 4 * hl)
            nw = (b2 - a2) // L
            rough = 0.0
            if nw >= 3:
                tw = np.arange(L) - (L - 1) / 2
                segs = xs_[: nw * L].reshape(nw, L)
                segs = segs - segs.mean(axis=1, keepdims=True)
                slope = (segs @ tw) / (tw @ tw)
                rough = float(np.median(np.sqrt(np.mean((segs - slope[:, None] * tw) ** 2, axis=1))))
            if cv > stick_slip_tol + 2.0 * expected_cv or rough > 3.0 * resolution / np.sqrt(12.0) + 1e-300:
                p.dropped = f"velocity oscillation (stick-slip), CV {cv:.2f}"
                out.rejected.append(p)
                continue
        if abs(x[b2 - 1] - x[a2]) < min_travel:
            p.dropped = "too short a travel (creep)"
            out.rejected.append(p)
            continue
        if require_dissipative and np.sign(p.force) != np.sign(vel):
            p.dropped = "force does not oppose the motion (pre-sliding)"
            out.rejected.append(p)
            continue
        if not ok.all():
            w = np.diff(edges)[ok]
            p.velocity = float(np.sum(vel_b[ok] * w) / np.sum(w))
        p.force_stderr = float(f_b[ok].std(ddof=1) / np.sqrt(ok.sum()))
        out.plateaus.append(p)
    return out


def fit_static_map(
    velocity: ArrayLike,
    force: ArrayLike,
    *,
    force_stderr: ArrayLike | None = None,
    per_direction: bool = False,
    bootstrap: int = 0,
    delta_bounds: tuple[float, float] = (0.2, 5.0),
    seed: int | None = 0,
    velocity_unit: str = "m/s",
    force_unit: str = "N",
    progress: bool = True,
) -> IdentificationResult:
    """Fit paper eq. 2 to steady ``(velocity, force)`` points by nonlinear least squares.

    All five parameters ``fc fs vs sigma delta`` are fitted (``scipy.optimize.least_squares``,
    multi-start over ``vs`` and ``delta``), standard errors from the Jacobian
    (``s^2 (J^T J)^-1``, ``s^2`` from the residuals).  Both directions share the parameters
    (``F(-v) = -F(v)``); with ``per_direction`` each direction is also fitted on its own and
    reported under ``info["directions"]``.

    Parameters
    ----------
    velocity, force : array_like
        Steady points, both signs of velocity allowed; units are the data's own.
    force_stderr : array_like, optional
        Standard error of each point (weights ``1/se``).
    per_direction : bool
        Also fit ``v > 0`` and ``v < 0`` separately.
    bootstrap : int
        Number of bootstrap resamples (cases) for a second, distribution-free standard error,
        reported as ``info["bootstrap_stderr"]``.
    delta_bounds : (float, float)
        Bounds on the shape exponent.
    seed : int, optional
        Seed of the bootstrap.
    velocity_unit, force_unit : str
        Units of the data (any :mod:`gmsfric.units` reads; a rotary axis gives ``rad/s`` and
        ``N m``).  The parameters are reported in them; ``model_object`` is converted to SI.

    Returns
    -------
    IdentificationResult
        ``model="static_map"``, parameters ``fc fs vs sigma delta``; ``model_object`` the
        :class:`~gmsfric.models.StaticFriction` in SI.

    Raises
    ------
    UnitError
        ``velocity_unit`` or ``force_unit`` unknown or not of their quantity (before any work).
    """
    units = static_map_units(velocity_unit, force_unit)
    v = as_array("velocity", velocity)
    F = as_array("force", force)
    same_length("force", F, "velocity", v.size)
    if force_stderr is None:
        se = np.ones_like(v)
    else:
        se = as_array("force_stderr", force_stderr)
        same_length("force_stderr", se, "velocity", v.size)
        pos = se[se > 0]
        floor = 1e-3 * float(np.median(pos)) if pos.size else 1.0
        se = np.maximum(se, floor)
    keep = v != 0
    v, F, se = v[keep], F[keep], se[keep]
    if v.size < MIN_POINTS:
        raise IdentificationError(f"too few constant-velocity points with non-zero velocity: {v.size}, need at least {MIN_POINTS}")
    if np.unique(np.round(np.abs(v), 12)).size < 4:
        raise IdentificationError(f"need at least 4 distinct speeds to fit 5 parameters, got {np.unique(np.abs(v)).size}")
    speed, mag, w = np.abs(v), np.sign(v) * F, 1.0 / se
    q, params, r = _fit_side(speed, mag, w, delta_bounds)
    # covariance of (fc, fs, vs, sigma, delta) from that of (fc, fs, log vs, sigma, log delta)
    fc_, fs_, vs_, sig_, de_ = _to_params(q)
    cov = transform_covariance(covariance_from_jacobian(r.jac, r.fun), np.diag([1.0, 1.0, vs_, 1.0, de_]))
    info: dict[str, Any] = {
        "n_points": int(v.size),
        "rms_residual": float(np.sqrt(np.mean((static_map_curve(v, *[params[k][0] for k in NAMES]) - F) ** 2))),
    }
    if per_direction:
        dirs = {}
        for name, mask in (("positive", v > 0), ("negative", v < 0)):
            if mask.sum() < MIN_POINTS or np.unique(speed[mask]).size < 4:
                raise IdentificationError(f"per-direction fit: only {int(mask.sum())} points with {name} velocity, need at least {MIN_POINTS} at 4 distinct speeds")
            _, p_dir, _ = _fit_side(speed[mask], mag[mask], w[mask], delta_bounds)
            dirs[name] = {k: {"value": val, "stderr": s} for k, (val, s) in p_dir.items()}
        info["directions"] = dirs
    if bootstrap > 0:
        rng = np.random.default_rng(seed)
        draws = []
        with Progress("static map bootstrap", total=bootstrap, enabled=progress) as prog:
            for _ in range(int(bootstrap)):
                idx = rng.integers(0, v.size, v.size)
                if np.unique(speed[idx]).size < 4:
                    prog.update()
                    continue
                try:
                    qb, _ = _one_sided_fit(speed[idx], mag[idx], w[idx], delta_bounds)
                    draws.append(_to_params(qb))
                except IdentificationError:  # pragma: no cover
                    pass
                prog.update()
        if len(draws) >= 2:
            arr = np.array(draws)
            info["bootstrap_stderr"] = {k: float(s) for k, s in zip(NAMES, arr.std(axis=0, ddof=1))}
            info["bootstrap_n"] = len(draws)
    res = IdentificationResult("static_map", params, units, info, data={"velocity": v, "force": F, "force_stderr": se},
                               model_object=static_friction_si({k: p[0] for k, p in params.items()}, units), covariance=(list(NAMES), cov))
    return res


def fit_static_map_from_run(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    min_plateaus: int = MIN_POINTS,
    per_direction: bool = False,
    bootstrap: int = 0,
    velocity_unit: str = "m/s",
    force_unit: str = "N",
    progress: bool = True,
    **plateau_options: Any,
) -> IdentificationResult:
    """Find the constant-velocity plateaus of a raw run, average the force on each, fit eq. 2.

    Parameters
    ----------
    t, position, force : array_like
        Raw closed-loop record through constant-velocity plateaus in both directions.
    min_plateaus : int
        Fewer usable plateaus raise :class:`~gmsfric.errors.IdentificationError`.
    per_direction, bootstrap, velocity_unit, force_unit, progress
        As in :func:`fit_static_map`.
    **plateau_options
        Passed to :func:`find_plateaus` (``window``, ``min_speed``, ``settle``, ...).

    Returns
    -------
    IdentificationResult
        As :func:`fit_static_map`, with ``info["plateaus"]`` and the rejected ones.
    """
    static_map_units(velocity_unit, force_unit)
    t = as_array("time", t, min_len=10)
    search = find_plateaus(t, position, force, **plateau_options)
    pl = search.plateaus
    if len(pl) < min_plateaus:
        raise IdentificationError(
            f"too few constant-velocity plateaus: found {len(pl)} usable ({len(search.rejected)} rejected as unsteady), need at least {min_plateaus}"
        )
    v = np.array([p.velocity for p in pl])
    F = np.array([p.force for p in pl])
    se = np.array([p.force_stderr for p in pl])
    res = fit_static_map(v, F, force_stderr=se, per_direction=per_direction, bootstrap=bootstrap, velocity_unit=velocity_unit, force_unit=force_unit, progress=progress)
    res.info["n_plateaus"] = len(pl)
    res.info["n_rejected"] = len(search.rejected)
    res.info["plateaus"] = [{"t_start": float(t[p.start]), "t_stop": float(t[p.stop - 1]), "velocity": p.velocity, "force": p.force, "force_stderr": p.force_stderr} for p in pl]
    res.data.update(t=t, position=np.asarray(position, float), raw_force=np.asarray(force, float), plateaus=pl, rejected=search.rejected)
    return res
