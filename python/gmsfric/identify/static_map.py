"""Static friction map (paper eq. 2) from constant-velocity tests.

``F(v) = sign(v) (fc + (fs - fc) exp(-|v/vs|^delta)) + sigma v``

Two entry points: :func:`fit_static_map` on a table of steady ``(velocity, force)`` points and
:func:`fit_static_map_from_run` on a raw closed-loop record ``(time, position, force)`` through
constant-velocity plateaus, which finds the plateaus itself (:func:`find_plateaus`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import stats
from scipy.optimize import least_squares, nnls

from .. import curves
from .. import units as _units
from .._progress import Progress
from .._validate import as_array, measured_signal, positive, same_length
from ..errors import FitWarning, IdentificationError, InvalidInputError
from ..models import StaticFriction, Stribeck
from .diagnostics import Findings, check_bounds, check_chi2, check_stderr, emit
from .results import IdentificationResult, covariance_from_jacobian, transform_covariance
from .sampling import plateau_resolution, quantum, white_noise_level

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


def _bounds(speed: NDArray[np.float64], delta_bounds: tuple[float, float]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    lo = np.array([0.0, 0.0, np.log(speed.min()) - 6.0, 0.0, np.log(delta_bounds[0])])
    hi = np.array([np.inf, np.inf, np.log(speed.max()) + 6.0, np.inf, np.log(delta_bounds[1])])
    return lo, hi


def _starts(speed: NDArray[np.float64], force: NDArray[np.float64], delta_bounds: tuple[float, float]) -> list[NDArray[np.float64]]:
    """Start values: fc and sigma from a line through the faster half, fs from the slowest
    points, ``vs`` over 6 values spanning the data and ``delta`` in {0.7, 1, 2}."""
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
    out = []
    for vs0 in np.exp(np.linspace(np.log(speed.min()), np.log(speed.max()), 6)):
        for d0 in (0.7, 1.0, 2.0):
            out.append(np.array([fc0, fs0 + 1e-3 * scale, np.log(vs0), sig0, np.log(float(np.clip(d0, *delta_bounds)))]))
    return out


def _one_sided_fit(speed: NDArray[np.float64], force: NDArray[np.float64], weight: NDArray[np.float64], delta_bounds: tuple[float, float],
                   starts: list[NDArray[np.float64]] | None = None) -> tuple[NDArray[np.float64], Any]:
    """Fit ``|F|`` against ``|v|`` (all speeds > 0) from several starts (or the given ones);
    returns the internal vector and the least_squares result."""

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        return (static_map_curve(speed, *_to_params(q)) - force) * weight

    lo, hi = _bounds(speed, delta_bounds)
    best = None
    for q0 in starts if starts is not None else _starts(speed, force, delta_bounds):
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


def _fit_side(speed, force, weight, delta_bounds, known_errors=False):  # type: ignore[no-untyped-def]
    """Fit and covariance.  With known standard errors of the points (``known_errors``) the
    covariance is ``(J^T W J)^-1``, scaled up by chi2/dof when the scatter exceeds them but never
    down (a few points scattering less than their errors say is no reason to trust the fit more);
    otherwise ``s^2 (J^T J)^-1`` with ``s^2`` from the residuals."""
    q, r = _one_sided_fit(speed, force, weight, delta_bounds)
    cov = covariance_from_jacobian(r.jac, r.fun)
    if known_errors:
        dof = max(r.fun.size - r.x.size, 1)
        s2 = float(r.fun @ r.fun) / dof
        cov = cov / max(s2, 1e-300) * max(s2, 1.0)
    return q, _external(q, cov), r


def _diagnose(findings: Findings, q: NDArray[np.float64], params: dict[str, tuple[float, float]], speed: NDArray[np.float64],
              delta_bounds: tuple[float, float], chi2: float | None, dof: int, units: dict[str, str]) -> set[str]:
    """Findings of a static-map fit (SI values, reported in ``units``); returns the parameters
    at a bound of zero."""
    fc, fs, vs, sigma, delta = (params[k][0] for k in NAMES)
    lo, hi = _bounds(speed, delta_bounds)
    zero = set()
    for name, value in (("fc", fc), ("fs", fs), ("sigma", sigma)):
        if value <= 1e-9 * max(fc, fs, 1e-300) or value == 0.0:
            zero.add(name)
            findings.add("at_bound", f"{name} is at its lower bound 0", name)
    check_bounds(findings, "delta", delta, *delta_bounds, what=" (the Stribeck shape is not determined: vs and fs are unreliable too)")
    check_bounds(findings, "vs", vs, float(np.exp(lo[2])), float(np.exp(hi[2])), log=True, what=" (far outside the measured speeds)")
    if fs < fc and "fs" not in zero:
        findings.add("ordering", f"fs < fc ({fs:.4g} < {fc:.4g} {units['fc']}): friction rising from rest is not a static map eq. 2 "
                                 "can stand for (wrong force column or units, or no Stribeck drop in the data)", "fs")
    if vs < speed.min():
        findings.add("coverage", f"vs = {vs:.3g} {units['vs']} is below the slowest point ({speed.min():.3g} {units['vs']}): the Stribeck drop "
                                 "is not sampled, so vs, delta and fs are extrapolated", "vs")
    elif vs > speed.max():
        findings.add("coverage", f"vs = {vs:.3g} {units['vs']} is above the fastest point ({speed.max():.3g} {units['vs']}): the Coulomb "
                                 "level is not reached, so fc and sigma are extrapolated", "vs")
    if chi2 is not None:
        check_chi2(findings, chi2, dof, what=" of the static map (with the points' standard errors)", low=None)
    check_stderr(findings, params, skip=zero)
    return zero


def _drop_significance(speed: NDArray[np.float64], force: NDArray[np.float64], weight: NDArray[np.float64], rss: float,
                       known_errors: bool) -> float:
    """p-value of the Stribeck drop: the fit against the map without one (``fs = fc``, i.e. the
    line ``fc + sigma v``, fitted with ``fc, sigma >= 0``), by an F-test on the three parameters
    ``fs, vs, delta`` (a chi2 test with known point errors).  A large p: the data show no drop,
    so ``fs``, ``vs`` and ``delta`` are extrapolated, whatever their standard errors say."""
    a = np.column_stack([np.ones_like(speed), speed]) * weight[:, None]
    coef, _ = nnls(a, force * weight)
    r0 = a @ coef - force * weight
    rss0 = float(r0 @ r0)
    dof = speed.size - len(NAMES)
    if dof < 1:
        return 1.0
    gain = max(rss0 - rss, 0.0)
    if known_errors:
        # chi2 scaled by the residual when it exceeds the stated errors (as the covariance is)
        scale = max(rss / dof, 1.0)
        return float(stats.chi2.sf(gain / scale, 3))
    if rss <= 1e-300:
        return 0.0 if gain > 0 else 1.0
    return float(stats.f.sf((gain / 3.0) / (rss / dof), 3, dof))


def _check_drop(findings: Findings, p_drop: float, params: dict[str, tuple[float, float]], speed: NDArray[np.float64], units: dict[str, str]) -> None:
    """Flag a Stribeck drop the data do not show (the map is then a line through the points)."""
    if p_drop > DROP_P_VALUE and not findings.has("coverage", "vs"):
        findings.add("coverage", f"the data show no significant Stribeck drop (p = {p_drop:.2g} against a line fc + sigma v; slowest point "
                                 f"{speed.min():.3g} {units['vs']}): fs, vs and delta are not identified by these data, whatever their "
                                 "standard errors (measure slower, down to where the friction rises)", "fs")


def _flipped_sign(speed_signed: NDArray[np.float64], force: NDArray[np.float64]) -> bool:
    """Most points' force opposes their velocity: a force in the reaction convention."""
    return bool(np.mean(np.sign(speed_signed) * force < 0) > 0.75)


#: A Stribeck drop whose F-test p-value exceeds this is not shown by the data.
DROP_P_VALUE = 0.01

#: What a force of the wrong sign is told.
SIGN_MESSAGE = ("the force has the opposite sign to the velocity on most points: friction opposes the motion, and gmsfric expects the force "
                "applied to the axis (the drive force that overcomes friction, with the sign of the motion), not the friction's reaction on "
                "it; negate the force column")


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


def _moving_segments(v: NDArray[np.float64], used: NDArray[np.int64], n_blocks: int, rel_tol: float) -> list[tuple[int, int, int]]:
    """Stretches of motion of one sign, split where the velocity changes by more than
    ``rel_tol``; each with the half-width of its velocity window."""
    n = v.size
    sgn = np.sign(v)
    edges = np.flatnonzero(np.diff(sgn) != 0) + 1
    bounds = np.concatenate(([0], edges, [n]))
    segments: list[tuple[int, int, int]] = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if sgn[a] == 0:
            continue
        h = int(np.median(used[a:b]))
        if b - a < 6 * h or b - a < 3 * n_blocks:
            continue
        parts: list[tuple[int, int]] = []
        _split(v, int(a), int(b), rel_tol, max(3 * h, n_blocks), parts)
        segments.extend((p0, p1, h) for p0, p1 in parts)
    return segments


def _block_stats(t: NDArray[np.float64], x: NDArray[np.float64], f: NDArray[np.float64], edges: NDArray[np.int64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    vel = np.array([(x[e1 - 1] - x[e0]) / (t[e1 - 1] - t[e0]) for e0, e1 in zip(edges[:-1], edges[1:])])
    force = np.array([f[e0:e1].mean() for e0, e1 in zip(edges[:-1], edges[1:])])
    return vel, force


def _settled_blocks(vel: NDArray[np.float64], force: NDArray[np.float64], noise: float, tol: float, vel_res: float) -> NDArray[np.bool_]:
    """Sub-blocks of a plateau in steady motion: leading and trailing blocks whose velocity or
    force is off the rest (the end of an acceleration, the loop settling, the start of the
    deceleration) are dropped one by one; ``noise`` is the scatter a block mean has anyway."""
    keep = np.ones(vel.size, dtype=bool)

    def off(j: int) -> bool:
        rest = keep.copy()
        rest[j] = False
        fm = float(np.median(force[rest]))
        spread = max(1.4826 * float(np.median(np.abs(force[rest] - fm))), noise)
        vm = float(np.median(vel[rest]))
        return abs(force[j] - fm) > 4.0 * spread or abs(vel[j] - vm) > tol * abs(vm) + vel_res

    changed = True
    while changed and keep.sum() > 3:
        changed = False
        idx = np.flatnonzero(keep)
        for j in (idx[0], idx[-1]):
            if keep.sum() > 3 and off(int(j)):
                keep[j] = False
                changed = True
    return keep


def _stick_slip(t: NDArray[np.float64], x: NDArray[np.float64], a: int, b: int, vel: float, resolution: float, quantum_: float, dt: float,
                tol: float) -> str:
    """Why the motion on ``[a, b)`` is not steady sliding (empty when it is): standstills (the
    encoder stops for much longer than quantum / speed), velocity oscillation, a rough path."""
    if quantum_ > 0:
        ch = np.flatnonzero(np.diff(x[a:b]) != 0)
        if ch.size > 2:
            gaps = np.diff(t[a:b][ch])
            expected = max(quantum_ / abs(vel), dt)
            stuck = float(gaps[gaps > 4.0 * expected].sum()) / max(float(t[b - 1] - t[a]), dt)
            if stuck > 0.2:
                return f"stick-slip ({stuck:.0%} of the plateau at standstill)"
    # local velocity over ~8 resolutions scatters far more than quantisation explains
    hl = max(1, int(np.ceil(8.0 * resolution / (abs(vel) * dt) / 2)))
    if b - a > 4 * hl:
        xs = x[a:b]
        v_loc = (xs[2 * hl :] - xs[: -2 * hl]) / (2 * hl * dt)
        cv = float(np.std(v_loc)) / abs(vel)
        expected_cv = resolution / (2 * hl * dt * abs(vel))
        L = max(10, 4 * hl)
        nw = (b - a) // L
        rough = 0.0
        if nw >= 3:
            # short-window roughness of the position about its local straight line
            tw = np.arange(L) - (L - 1) / 2
            segs = xs[: nw * L].reshape(nw, L)
            segs = segs - segs.mean(axis=1, keepdims=True)
            slope = (segs @ tw) / (tw @ tw)
            rough = float(np.median(np.sqrt(np.mean((segs - slope[:, None] * tw) ** 2, axis=1))))
        if cv > tol + 2.0 * expected_cv or rough > 3.0 * resolution / np.sqrt(12.0) + 1e-300:
            return f"velocity oscillation (stick-slip), CV {cv:.2f}"
    return ""


def _examine(t: NDArray[np.float64], x: NDArray[np.float64], f: NDArray[np.float64], a: int, b: int, h: int, *, settle: float, n_blocks: int,
             tol: float, resolution: float, quantum_: float, force_noise: float, min_travel: float, require_dissipative: bool,
             dt: float) -> Plateau | None:
    """One constant-velocity stretch: its transient dropped, judged steady or not; ``None`` when
    too short to judge."""
    # the velocity window smears the start and the stop by h samples
    a2 = a + max(2 * h, int(settle * (b - a)))
    b2 = b - 2 * h
    if b2 - a2 < max(n_blocks * 3, 2 * h):
        return None
    edges = np.linspace(a2, b2, n_blocks + 1).astype(int)
    vel_b, f_b = _block_stats(t, x, f, edges)
    block_len = float(np.median(np.diff(edges)))
    vel_res = 2.0 * resolution / max(float(t[edges[1] - 1] - t[edges[0]]), dt)
    keep = _settled_blocks(vel_b, f_b, force_noise / np.sqrt(block_len), tol, vel_res)
    ok = np.flatnonzero(keep)
    a3, b3 = int(edges[ok[0]]), int(edges[ok[-1] + 1])
    vel = float(np.polyfit(t[a3:b3] - t[a3], x[a3:b3], 1)[0]) if b3 - a3 > 2 else 0.0
    p = Plateau(a3, b3, vel, float(f_b[keep].mean()), float("nan"), float(keep.mean()))
    if keep.sum() < max(3, n_blocks // 2) or vel == 0:
        p.dropped = "unsteady velocity or force (transient or stick-slip)"
        return p
    reason = _stick_slip(t, x, a3, b3, vel, resolution, quantum_, dt, tol)
    if reason:
        p.dropped = reason
        return p
    if abs(x[b3 - 1] - x[a3]) < min_travel:
        p.dropped = "too short a travel (creep)"
        return p
    if require_dissipative and np.sign(p.force) != np.sign(vel):
        p.dropped = "force does not oppose the motion (pre-sliding)"
        return p
    p.force_stderr = float(f_b[keep].std(ddof=1) / np.sqrt(keep.sum()))
    return p


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
    n_blocks: int = 16,
    min_travel: float | None = None,
    require_dissipative: bool = True,
    min_duration: float = 0.2,
) -> PlateauSearch:
    """Constant-velocity plateaus of a raw run, transients and stick-slip stretches dropped.

    Stages: the velocity by centred differences whose width adapts to the speed (the smallest
    spanning ``counts`` position resolutions, so slow and fast plateaus are resolved alike);
    stretches of one sign split where the velocity changes by more than ``rel_tol``; in each, the
    first ``settle`` fraction dropped, then leading and trailing sub-blocks whose force or
    velocity is off the rest (acceleration, settling, deceleration); stick-slip (standstills,
    velocity oscillation), creep and non-dissipative stretches rejected; finally plateaus much
    shorter than the others (creep while the loop settles).

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
        unsteady; plateaus keeping less than half of their blocks are rejected.
    n_blocks : int
        Sub-blocks per plateau (>= 4), also used for the standard error of the mean force
        (``std(block means) / sqrt(n)``).
    min_travel : float, optional
        Shortest distance travelled on a kept plateau; shorter ones (creep while settling) are
        rejected.  Default: ``2 * counts`` position resolutions.
    require_dissipative : bool
        Reject plateaus whose mean force does not have the sign of the velocity (pre-sliding or
        creep, not steady sliding).
    min_duration : float
        Plateaus shorter than this fraction of the median kept plateau are rejected.

    Returns
    -------
    PlateauSearch
        ``plateaus`` (kept) and ``rejected``.
    """
    t = measured_signal("time", t, min_len=10)
    x = measured_signal("position", position)
    f = measured_signal("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", f, "time", t.size)
    if isinstance(n_blocks, bool) or int(n_blocks) != n_blocks or n_blocks < 4:
        raise InvalidInputError(f"`n_blocks` must be an integer >= 4, got {n_blocks!r}")
    dt = float(np.median(np.diff(t)))
    if max_window is None:
        max_window = (t[-1] - t[0]) / 50.0
    max_h = max(2, int(round(positive("max_window", max_window) / dt)))
    resolution = plateau_resolution(x)
    q = quantum(x)
    if min_travel is None:
        min_travel = 2.0 * counts * resolution
    v, used = _adaptive_velocity(t, x, resolution, counts, max_h)
    out = PlateauSearch(window=float(np.median(used[used > 0]) * dt) if np.any(used > 0) else 0.0)
    force_noise = white_noise_level(f)
    for a, b, h in _moving_segments(v, used, int(n_blocks), rel_tol):
        p = _examine(t, x, f, a, b, h, settle=settle, n_blocks=int(n_blocks), tol=stick_slip_tol, resolution=resolution, quantum_=q,
                     force_noise=force_noise, min_travel=min_travel, require_dissipative=require_dissipative, dt=dt)
        if p is None:
            continue
        (out.rejected if p.dropped else out.plateaus).append(p)
    if out.plateaus:
        durations = np.array([t[p.stop - 1] - t[p.start] for p in out.plateaus])
        short = durations < min_duration * float(np.median(durations))
        for p in [p for p, sh in zip(out.plateaus, short) if sh]:
            p.dropped = "much shorter than the other plateaus (creep while settling)"
            out.rejected.append(p)
        out.plateaus = [p for p, sh in zip(out.plateaus, short) if not sh]
    return out

#: Speeds (SI) a static map is fitted over: below a picometre per second no friction curve is
#: measured, beyond a kilometre per second no axis moves; outside, the fit only crawls.
SPEED_RANGE = (1e-12, 1e3)


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
    reported under ``info["directions"]``.  The points are converted to SI before the fit.

    Parameters
    ----------
    velocity, force : array_like
        Steady points, both signs of velocity allowed, in ``velocity_unit`` and ``force_unit``.
    force_stderr : array_like, optional
        Standard error of each point (weights ``1/se``; then chi2/dof is checked).
    per_direction : bool
        Also fit ``v > 0`` and ``v < 0`` separately.
    bootstrap : int
        Number of bootstrap resamples (cases) for a second, distribution-free standard error,
        reported as ``info["bootstrap_stderr"]``; each draw starts from the fit.
    delta_bounds : (float, float)
        Bounds on the shape exponent.
    seed : int, optional
        Seed of the bootstrap.
    velocity_unit, force_unit : str
        Units of the data (any :mod:`gmsfric.units` reads; a rotary axis gives ``rad/s`` and
        ``N m``).  The parameters are reported in them; ``model_object`` is in SI.

    Returns
    -------
    IdentificationResult
        ``model="static_map"``, parameters ``fc fs vs sigma delta``; ``model_object`` the
        :class:`~gmsfric.models.StaticFriction` in SI.

    Raises
    ------
    InvalidInputError
        Bad arguments (before any work).
    UnitError
        ``velocity_unit`` or ``force_unit`` unknown or not of their quantity (before any work).
    IdentificationError
        Too few points or distinct speeds.
    """
    units = static_map_units(velocity_unit, force_unit)
    v_u = measured_signal("velocity", velocity)
    F_u = measured_signal("force", force)
    same_length("force", F_u, "velocity", v_u.size)
    if isinstance(bootstrap, bool) or int(bootstrap) != bootstrap or bootstrap < 0:
        raise InvalidInputError(f"`bootstrap` must be an integer >= 0, got {bootstrap!r}")
    if not (0 < delta_bounds[0] < delta_bounds[1]):
        raise InvalidInputError(f"`delta_bounds` must be (low, high) with 0 < low < high, got {delta_bounds!r}")
    kv = _units.factor(velocity_unit, "velocity", name="velocity_unit")
    kf = _units.factor(force_unit, "force", name="force_unit")
    if force_stderr is None:
        se_u = np.ones_like(v_u)
    else:
        se_u = as_array("force_stderr", force_stderr)
        same_length("force_stderr", se_u, "velocity", v_u.size)
        pos = se_u[se_u > 0]
        floor = 1e-3 * float(np.median(pos)) if pos.size else 1.0
        se_u = np.maximum(se_u, floor)
    keep = v_u != 0
    v_u, F_u, se_u = v_u[keep], F_u[keep], se_u[keep]
    if v_u.size < MIN_POINTS:
        raise IdentificationError(f"too few constant-velocity points with non-zero velocity: {v_u.size}, need at least {MIN_POINTS}")
    if np.unique(np.round(np.abs(v_u) / np.abs(v_u).max(), 12)).size < 4:
        raise IdentificationError(f"need at least 4 distinct speeds to fit 5 parameters, got {np.unique(np.abs(v_u)).size}")
    # the fit runs in SI (scale-free: logs of vs and delta, relative weights)
    v, F, se = v_u * kv, F_u * kf, se_u * (kf if force_stderr is not None else 1.0)
    fastest = float(np.abs(v).max())
    if not SPEED_RANGE[0] <= fastest <= SPEED_RANGE[1]:
        raise InvalidInputError(f"`velocity`: the fastest point is {fastest:.3g} (SI, m/s or rad/s), outside the "
                                f"{SPEED_RANGE[0]:g} to {SPEED_RANGE[1]:g} a static map can be fitted over; check `velocity_unit`")
    speed, mag, w = np.abs(v), np.sign(v) * F, 1.0 / se
    known = force_stderr is not None
    q, params_si, r = _fit_side(speed, mag, w, delta_bounds, known)
    fc_, fs_, vs_, sig_, de_ = _to_params(q)
    cov_q = covariance_from_jacobian(r.jac, r.fun)
    if known:
        s2 = float(r.fun @ r.fun) / max(r.fun.size - r.x.size, 1)
        cov_q = cov_q / max(s2, 1e-300) * max(s2, 1.0)
    # covariance of (fc, fs, vs, sigma, delta) from that of (fc, fs, log vs, sigma, log delta)
    cov_si = transform_covariance(cov_q, np.diag([1.0, 1.0, vs_, 1.0, de_]))
    to_user = {"fc": 1 / kf, "fs": 1 / kf, "vs": 1 / kv, "sigma": kv / kf, "delta": 1.0}
    params = {k: (val * to_user[k], e * to_user[k]) for k, (val, e) in params_si.items()}
    info: dict[str, Any] = {
        "n_points": int(v.size),
        "rms_residual": float(np.sqrt(np.mean((static_map_curve(v, fc_, fs_, vs_, sig_, de_) - F) ** 2))) / kf,
    }
    dof = max(v.size - len(NAMES), 1)
    chi2 = float(r.fun @ r.fun) if force_stderr is not None else None
    if chi2 is not None:
        info["chi2_per_dof"] = chi2 / dof
    findings = Findings()
    if _flipped_sign(v, F):
        findings.add("ordering", SIGN_MESSAGE, None)
    zero = _diagnose(findings, q, params, speed / kv, delta_bounds, chi2, dof, units)
    p_drop = _drop_significance(speed, mag, w, float(r.fun @ r.fun), known)
    info["drop_p_value"] = p_drop
    _check_drop(findings, p_drop, params, speed / kv, units)
    for name in zero:
        params[name] = (0.0, params[name][1])
    if per_direction:
        dirs = {}
        for name, mask in (("positive", v > 0), ("negative", v < 0)):
            if mask.sum() < MIN_POINTS or np.unique(speed[mask]).size < 4:
                raise IdentificationError(f"per-direction fit: only {int(mask.sum())} points with {name} velocity, need at least {MIN_POINTS} at 4 distinct speeds")
            _, p_dir, _ = _fit_side(speed[mask], mag[mask], w[mask], delta_bounds, known)
            dirs[name] = {k: {"value": val * to_user[k], "stderr": e * to_user[k]} for k, (val, e) in p_dir.items()}
        info["directions"] = dirs
    if bootstrap > 0:
        draws = _bootstrap(speed, mag, w, q, delta_bounds, int(bootstrap), seed, progress)
        if len(draws) >= 2:
            arr = np.array(draws)
            info["bootstrap_stderr"] = {k: float(sd) * to_user[k] for k, sd in zip(NAMES, arr.std(axis=0, ddof=1))}
            info["bootstrap_n"] = len(draws)
    scale = np.array([to_user[k] for k in NAMES])
    res = IdentificationResult("static_map", params, units, info, data={"velocity": v_u, "force": F_u, "force_stderr": se_u},
                               model_object=static_friction_si({k: p[0] for k, p in params.items()}, units),
                               covariance=(list(NAMES), cov_si * np.outer(scale, scale)))
    emit(res, findings)
    return res


def _bootstrap(speed: NDArray[np.float64], force: NDArray[np.float64], weight: NDArray[np.float64], q: NDArray[np.float64],
               delta_bounds: tuple[float, float], n: int, seed: int | None, progress: bool) -> list[tuple[float, ...]]:
    """Case-resampling bootstrap, every draw started from the fit (a resample moves the optimum
    a little: one local fit finds it, the multi-start search is not needed again)."""
    rng = np.random.default_rng(seed)
    draws = []
    with Progress("static map bootstrap", total=n, enabled=progress) as prog:
        for _ in range(n):
            idx = rng.integers(0, speed.size, speed.size)
            if np.unique(speed[idx]).size >= 4:
                try:
                    qb, _ = _one_sided_fit(speed[idx], force[idx], weight[idx], delta_bounds, starts=[q])
                    draws.append(_to_params(qb))
                except IdentificationError:  # pragma: no cover
                    pass
            prog.update()
    return draws


def fit_static_map_from_run(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    min_plateaus: int = MIN_POINTS,
    per_direction: bool = False,
    bootstrap: int = 0,
    position_unit: str | None = None,
    time_unit: str = "s",
    velocity_unit: str | None = None,
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
    per_direction, bootstrap, force_unit, progress
        As in :func:`fit_static_map`.
    position_unit, time_unit : str
        Units of the position and time columns (converted to SI before anything else).
    velocity_unit : str, optional
        Unit the velocities are reported in; default ``position_unit/time_unit``.  Without
        ``position_unit`` it also states the run's velocity unit (``mm/s`` for a run in mm and s).
    **plateau_options
        Passed to :func:`find_plateaus` (``counts``, ``settle``, ``rel_tol``, ...).

    Returns
    -------
    IdentificationResult
        As :func:`fit_static_map`, with ``info["plateaus"]`` (in the reported units) and the
        number rejected.
    """
    if position_unit is not None:
        rotary = _units.is_rotary(position_unit, "position", name="position_unit")
        _units.check(time_unit, "time", name="time_unit")
        run_velocity = _units.ratio(position_unit, time_unit)
        velocity_unit = velocity_unit or run_velocity
        if _units.is_rotary(velocity_unit, "velocity", name="velocity_unit") != rotary:
            raise _units.UnitError(f"`velocity_unit` {velocity_unit!r} and `position_unit` {position_unit!r} are of different axes (linear/rotary)")
        kx = _units.factor(position_unit, "position", name="position_unit")
        kt = _units.factor(time_unit, "time", name="time_unit")
    else:
        velocity_unit = velocity_unit or "m/s"
        # the run's own velocity unit carries both: positions scaled by it, time kept
        kx, kt = _units.factor(velocity_unit, "velocity", name="velocity_unit"), 1.0
    static_map_units(velocity_unit, force_unit)
    kv_report = _units.factor(velocity_unit, "velocity", name="velocity_unit")
    kf = _units.factor(force_unit, "force", name="force_unit")
    t_u = measured_signal("time", t, min_len=10)
    x_u = measured_signal("position", position)
    F_u = measured_signal("force", force)
    same_length("position", x_u, "time", t_u.size)
    same_length("force", F_u, "time", t_u.size)
    # SI once: the plateau search and the fit see SI numbers only
    t_si, x_si, F_si = t_u * kt, x_u * kx, F_u * kf
    search = find_plateaus(t_si, x_si, F_si, **plateau_options)
    pl = search.plateaus
    if len(pl) < min_plateaus:
        raise IdentificationError(
            f"too few constant-velocity plateaus: found {len(pl)} usable ({len(search.rejected)} rejected as unsteady), need at least {min_plateaus}"
        )
    v = np.array([p.velocity for p in pl]) / kv_report
    F = np.array([p.force for p in pl]) / kf
    se = np.array([p.force_stderr for p in pl]) / kf
    res = fit_static_map(v, F, force_stderr=se, per_direction=per_direction, bootstrap=bootstrap, velocity_unit=velocity_unit, force_unit=force_unit,
                         progress=progress)
    res.info["n_plateaus"] = len(pl)
    res.info["n_rejected"] = len(search.rejected)
    res.info["plateaus"] = [{"t_start": float(t_u[p.start]), "t_stop": float(t_u[p.stop - 1]), "velocity": p.velocity / kv_report, "force": p.force / kf,
                             "force_stderr": p.force_stderr / kf} for p in pl]
    if len(search.rejected) > 2 * len(pl):
        reasons = sorted({p.dropped.split(",")[0].split(" (")[0] for p in search.rejected})
        extra = {"code": "data", "parameter": None,
                 "message": f"{len(search.rejected)} of {len(search.rejected) + len(pl)} constant-velocity stretches were rejected ({'; '.join(reasons)})"}
        res.diagnostics.append(extra)
        warnings.warn(f"static_map: {extra['message']}", FitWarning, stacklevel=2)
    res.data.update(t=t_u, position=x_u, raw_force=F_u, plateaus=pl, rejected=search.rejected, to_user={"time": 1.0 / kt, "force": 1.0 / kf})
    return res
