"""Pre-sliding GMS blocks from the virgin-curve test (paper Section 3.2, eq. 6, Figs. 6-8).

Steps, all automatic:

1. Turning points of the position (sinusoids of a small and a large amplitude at one frequency).
2. Virgin curve by the Masing rule, as the paper does: every branch that starts at a turning point
   is shifted to the origin and halved, ``u = |x - x_r| / 2``, ``g = ±(F - F_r) / 2``; a branch is
   used only as far as the previous branch reached (beyond, the memory of the earlier turning
   point is wiped out and Masing no longer holds).  Branches of both amplitudes are combined.
3. The virgin curve of N Maxwell-slip blocks is ``g(u) = sum_i k_i min(u, d_i)``: piecewise
   linear through the origin with knots ``d_i`` and slopes ``K_0 = sum k_i``, ``K_a = sum_{i>1}
   k_i``, ... (eq. 6).  The knots come from an optimal (dynamic-programming) piecewise-linear
   segmentation of the binned curve (log-spaced bins), the number of blocks from BIC when not
   given; ``k_i`` follow from the slopes by eq. 6 and ``w_i = k_i d_i``.  A nonlinear
   least-squares fit of ``(k, d)`` on the binned curve polishes the knots.
4. All ``k_i, w_i`` are then refined by fitting the simulated GMS hysteresis (Rust
   ``simulate_friction`` along the measured position) to the measured force, with standard errors
   from the Jacobian.

Blocks are reported in order of break displacement ``d_i = w_i / k_i`` (eq. 6's order).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from .. import curves
from .. import units as _units
from .._progress import Progress
from .._validate import as_array, positive, same_length
from ..errors import IdentificationError, InvalidInputError
from ..models import GMS, Stribeck, simulate_friction
from .results import IdentificationResult, autocorrelation_inflation, covariance_from_jacobian, transform_covariance


@dataclass
class VirginCurve:
    """Virgin-curve points from Masing branches and their log-binned averages."""

    u: NDArray[np.float64]
    g: NDArray[np.float64]
    u_bin: NDArray[np.float64]
    g_bin: NDArray[np.float64]
    se_bin: NDArray[np.float64]
    count_bin: NDArray[np.int64]
    turning_points: NDArray[np.int64]
    resolution: float


def _moving_average(x: NDArray[np.float64], m: int) -> NDArray[np.float64]:
    if m <= 1:
        return x
    k = np.ones(m) / m
    pad = np.pad(x, (m // 2, m - 1 - m // 2), mode="edge")
    return np.convolve(pad, k, mode="valid")


def _zigzag(x: NDArray[np.float64], threshold: float) -> list[int]:
    """Indices of alternating extrema, each confirmed by a move of more than ``threshold``."""
    turns: list[int] = []
    direction = 0
    hi_i = lo_i = 0
    for i in range(1, x.size):
        if x[i] > x[hi_i]:
            hi_i = i
        if x[i] < x[lo_i]:
            lo_i = i
        if direction >= 0 and x[hi_i] - x[i] > threshold and (direction == 1 or x[hi_i] - x[0] > threshold):
            turns.append(hi_i)
            direction, lo_i = -1, i
        elif direction <= 0 and x[i] - x[lo_i] > threshold and (direction == -1 or x[0] - x[lo_i] > threshold):
            turns.append(lo_i)
            direction, hi_i = 1, i
    return turns


def _turning_points(x: NDArray[np.float64], resolution: float) -> list[int]:
    """Extrema of the position (the middle of a flat, quantised top)."""
    thr = 10.0 * resolution
    turns = _zigzag(x, thr)
    if len(turns) >= 2:
        m = max(1, int(np.median(np.diff(turns)) / 100))
        xs = _moving_average(x, m)
        turns = _zigzag(xs, thr)
        refined = []
        for j, i in enumerate(turns):
            lo, hi = max(0, i - m), min(x.size, i + m + 1)
            seg = xs[lo:hi]
            is_max = xs[i] >= xs[turns[j + 1]] if j + 1 < len(turns) else xs[i] >= xs[turns[j - 1]] if j else True
            target = seg.max() if is_max else seg.min()
            hits = np.flatnonzero(seg == target)
            refined.append(lo + int(hits[len(hits) // 2]))
        turns = refined
    return turns


def build_virgin_curve(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    n_bins: int = 80,
    resolution: float | None = None,
) -> VirginCurve:
    """The virgin curve of a sinusoid test by the Masing rule (combine, halve, shift; see the
    module docstring), with log-binned averages.

    Parameters
    ----------
    t, position, force : array_like
        The record (any consistent units).
    n_bins : int
        Log-spaced bins of ``u`` between the position resolution and the largest half-span.
    resolution : float, optional
        Position resolution (encoder quantum or noise level); estimated when not given.
    """
    t = as_array("time", t, min_len=10)
    x = as_array("position", position)
    F = as_array("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", F, "time", t.size)
    if resolution is None:
        dx = np.abs(np.diff(x))
        quantum = float(dx[dx > 0].min()) if np.any(dx > 0) else 0.0
        noise = 1.4826 * float(np.median(np.abs(np.diff(x, 2)))) / np.sqrt(6.0)
        resolution = max(quantum, noise, 1e-9 * max(float(np.ptp(x)), 1e-300))
    turns = _turning_points(x, resolution)
    if len(turns) < 3:
        raise IdentificationError(f"found {len(turns)} turning points of the position: need at least 3 (two full branches of a sinusoid test)")
    half = max(1, int(np.median(np.diff(turns)) / 200))
    us, gs = [], []
    bounds = turns + [x.size - 1]
    for j in range(1, len(turns)):
        r = turns[j]
        end = bounds[j + 1]
        span_prev = abs(x[r] - x[turns[j - 1]])
        xr = x[r]
        Fr = float(np.mean(F[max(0, r - half) : r + half + 1]))
        seg = slice(r, end + 1)
        direction = np.sign(x[end] - xr) or 1.0
        du = direction * (x[seg] - xr)
        ok = (du >= 0) & (du <= span_prev * (1 + 1e-9))
        us.append(du[ok] / 2)
        gs.append(direction * (F[seg][ok] - Fr) / 2)
    u = np.concatenate(us)
    g = np.concatenate(gs)
    pos = u > 0
    if pos.sum() < 20:
        raise IdentificationError("too few points on the virgin curve (are the sinusoid amplitudes above the position resolution?)")
    lo = max(resolution / 2, float(u[pos].min()))
    edges = np.geomspace(lo, float(u.max()) * (1 + 1e-12), n_bins + 1)
    idx = np.digitize(u, edges) - 1
    ub, gb, sb, cb = [], [], [], []
    for b in range(n_bins):
        m = idx == b
        c = int(m.sum())
        if c < 3:
            continue
        ub.append(float(np.mean(u[m])))
        gb.append(float(np.mean(g[m])))
        sb.append(float(np.std(g[m], ddof=1) / np.sqrt(c)))
        cb.append(c)
    if len(ub) < 6:
        raise IdentificationError(f"only {len(ub)} populated bins on the virgin curve: need at least 6")
    sb_arr = np.asarray(sb)
    floor = max(float(np.median(sb_arr)) * 0.1, 1e-12 * float(np.abs(gb).max()))
    return VirginCurve(u, g, np.asarray(ub), np.asarray(gb), np.maximum(sb_arr, floor), np.asarray(cb), np.asarray(turns), float(resolution))


def virgin_model(u: NDArray[np.float64], k: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sum_i k_i min(u, d_i)`` for ``u >= 0``: the virgin curve of blocks with knots ``d_i``
    (:func:`gmsfric.curves.virgin_curve` with break forces ``k_i d_i``)."""
    return curves.virgin_curve(u, k, k * d)


def _segment_dp(x: NDArray[np.float64], y: NDArray[np.float64], w: NDArray[np.float64], n_seg: int, min_pts: int = 2) -> list[int]:
    """Optimal segmentation of the (sorted) points into ``n_seg`` straight-line pieces (weighted
    least squares, dynamic programming); returns the start index of each piece after the first."""
    n = x.size
    W = np.concatenate(([0.0], np.cumsum(w)))
    X = np.concatenate(([0.0], np.cumsum(w * x)))
    Y = np.concatenate(([0.0], np.cumsum(w * y)))
    XX = np.concatenate(([0.0], np.cumsum(w * x * x)))
    XY = np.concatenate(([0.0], np.cumsum(w * x * y)))
    YY = np.concatenate(([0.0], np.cumsum(w * y * y)))

    def cost(i: NDArray[np.int64], j: int) -> NDArray[np.float64]:  # points i..j-1
        sw = W[j] - W[i]
        sx, sy = X[j] - X[i], Y[j] - Y[i]
        sxx, sxy, syy = XX[j] - XX[i], XY[j] - XY[i], YY[j] - YY[i]
        vxx = sxx - sx * sx / sw
        vxy = sxy - sx * sy / sw
        vyy = syy - sy * sy / sw
        safe = np.where(vxx > 0, vxx, 1.0)
        c = vyy - np.where(vxx > 0, vxy * vxy / safe, 0.0)
        return np.maximum(c, 0.0)

    best = np.full((n_seg + 1, n + 1), np.inf)
    arg = np.zeros((n_seg + 1, n + 1), dtype=np.int64)
    best[0, 0] = 0.0
    for s in range(1, n_seg + 1):
        for j in range(s * min_pts, n + 1):
            i = np.arange((s - 1) * min_pts, j - min_pts + 1)
            if i.size == 0:
                continue
            tot = best[s - 1, i] + cost(i, j)
            k = int(np.argmin(tot))
            best[s, j] = tot[k]
            arg[s, j] = i[k]
    cuts = []
    j = n
    for s in range(n_seg, 0, -1):
        i = int(arg[s, j])
        cuts.append(i)
        j = i
    return sorted(cuts)[1:]


def _fit_virgin(vc: VirginCurve, n_blocks: int) -> tuple[NDArray[np.float64], NDArray[np.float64], Any, float]:
    """Segmentation -> eq. 6 -> NLS polish; returns k, d (sorted by d), the least_squares result
    and the weighted residual sum of squares."""
    x = np.concatenate(([0.0], vc.u_bin))
    y = np.concatenate(([0.0], vc.g_bin))
    se = np.concatenate(([vc.se_bin.min()], vc.se_bin))
    w = 1.0 / se**2
    n_seg = n_blocks + 1
    if x.size < 2 * n_seg + 1:
        raise IdentificationError(f"{x.size - 1} virgin-curve bins cannot support {n_blocks} blocks")
    cuts = _segment_dp(np.log(np.maximum(x, vc.u_bin.min() / 2)), y, w, n_seg)
    bounds = [0] + cuts + [x.size]
    slopes = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a >= 2 and np.ptp(x[a:b]) > 0:
            slopes.append(np.polyfit(x[a:b], y[a:b], 1, w=np.sqrt(w[a:b]))[0])
        else:
            slopes.append(0.0)
    knots = np.array([np.sqrt(x[c - 1] * x[c]) if x[c - 1] > 0 else x[c] / 2 for c in cuts])
    # eq. 6: K_j slopes -> k_i = K_{i-1} - K_i with the last slope taken as 0
    K = np.maximum.accumulate(np.maximum(np.array(slopes[:-1]), 0.0)[::-1])[::-1]
    k0 = np.maximum(K - np.concatenate((K[1:], [0.0])), 1e-6 * max(K.max(), 1e-300))
    d0 = np.maximum(knots, 1e-12)
    # linear refinement of k for the chosen knots
    A = np.minimum(x[:, None], d0[None, :]) * np.sqrt(w)[:, None]
    from scipy.optimize import nnls

    k_lin, _ = nnls(A, y * np.sqrt(w))
    k0 = np.where(k_lin > 0, k_lin, k0)

    def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
        k, d = np.exp(q[:n_blocks]), np.exp(q[n_blocks:])
        return (virgin_model(x, k, d) - y) * np.sqrt(w)

    umin, umax = float(vc.u_bin.min()), float(vc.u_bin.max())
    kmax = 1e3 * max(float(np.abs(y).max()), 1e-300) / umin
    lo = np.concatenate((np.full(n_blocks, np.log(kmax) - 40), np.full(n_blocks, np.log(umin / 100))))
    # every block must break inside the measured range (a knot beyond it is not identifiable)
    hi = np.concatenate((np.full(n_blocks, np.log(kmax)), np.full(n_blocks, np.log(umax))))
    q0 = np.clip(np.concatenate((np.log(k0), np.log(d0))), lo + 1e-6, hi - 1e-6)
    r = least_squares(resid, q0, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=2000)
    k, d = np.exp(r.x[:n_blocks]), np.exp(r.x[n_blocks:])
    order = np.argsort(d)
    return k[order], d[order], r, float(2 * r.cost)


def _make_gms(k: NDArray[np.float64], w: NDArray[np.float64], c: float, stribeck: Stribeck | None, sigma: float, slip_law: str) -> GMS:
    return GMS.from_break_forces(k, w, c, stribeck=stribeck, sigma=sigma, slip_law=slip_law, scale="sum")  # type: ignore[arg-type]


def presliding_units(position_unit: str, force_unit: str, time_unit: str = "s") -> tuple[bool, dict[str, float]]:
    """Check the data units of a pre-sliding test; returns whether the axis is rotary and the
    factors to SI of position, force and time."""
    _units.check(time_unit, "time", name="time_unit")
    rotary = _units.is_rotary(position_unit, "position", name="position_unit")
    _units.check(force_unit, "force", rotary=rotary, name="force_unit")
    kx = _units.factor(position_unit, "position", name="position_unit")
    kf = _units.factor(force_unit, "force", name="force_unit")
    kt = _units.factor(time_unit, "time", name="time_unit")
    return rotary, {"position": kx, "force": kf, "time": kt}


def _gms_si(k: NDArray[np.float64], w: NDArray[np.float64], c: float, stribeck: Stribeck | None, sigma: float, slip_law: str,
            f: dict[str, float]) -> GMS:
    """The identified GMS (built in the data's units) converted to SI: every parameter scaled by
    its dimension, so the SI model simulates the same physics."""
    kx, kf, kt = f["position"], f["force"], f["time"]
    st = None if stribeck is None else Stribeck(stribeck.fc * kf, stribeck.fs * kf, stribeck.vs * kx / kt, stribeck.delta)
    c_si = c * kf / kt if slip_law == "time" else c / kx
    return _make_gms(k * (kf / kx), w * kf, c_si, st, sigma * kf * kt / kx, slip_law)


def fit_presliding(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    n_blocks: int | None = None,
    max_blocks: int = 6,
    stribeck: Stribeck | None = None,
    c: float | None = None,
    sigma: float = 0.0,
    slip_law: str = "time",
    stribeck_stderr: Mapping[str, float] | None = None,
    refine: bool = True,
    n_bins: int = 80,
    resolution: float | None = None,
    position_unit: str = "m",
    force_unit: str = "N",
    time_unit: str = "s",
    progress: bool = True,
) -> IdentificationResult:
    """Identify the GMS blocks ``k_i`` (force/position) and ``w_i`` (force) from a virgin-curve
    test (small and large sinusoids at one frequency; see the module docstring).

    Parameters
    ----------
    t, position, force : array_like
        The record, starting from rest (ideally the virgin state).
    n_blocks : int, optional
        Number of blocks; chosen by BIC over ``1..max_blocks`` when not given.
    max_blocks : int
        Largest number of blocks tried by BIC.
    stribeck : Stribeck, optional
        Shape of the sliding level for the hysteresis refinement (e.g. from the static-map fit),
        in the data's units; it is rescaled so that ``s(0) = sum(w)`` (eq. 6).  Default: a
        constant level.
    c : float, optional
        GMS attraction parameter for the refinement; default ``1 / vs`` of ``stribeck`` (the
        paper's statement) or a fast ``1e3 * sum(w) / (time unit)``.
    sigma : float
        Viscous coefficient used in the refinement.
    slip_law : {"time", "displacement"}
        GMS slip law of the refinement.
    stribeck_stderr : mapping, optional
        Standard errors of ``stribeck``'s ``fc, fs, vs, delta`` (e.g. from the static-map fit).
        Without it the standard errors are conditional on ``stribeck``; with it, the shift of the
        refined blocks when each Stribeck parameter moves by one standard error is added to
        their covariance (first-order propagation).
    refine : bool
        Refine by fitting the simulated hysteresis to the force (else stop at the virgin fit).
    n_bins : int
        Log-spaced bins of the virgin curve.
    resolution : float, optional
        Position resolution; estimated when not given.
    position_unit, force_unit, time_unit : str
        Units of the data (any :mod:`gmsfric.units` reads; a rotary axis gives ``rad`` and
        ``N m``).  The parameters are reported in them (``stribeck``, ``c`` and ``sigma`` are
        taken in them too).

    Returns
    -------
    IdentificationResult
        ``model="presliding"``, parameters ``k1..kN`` and ``w1..wN``; ``model_object`` is the
        refined :class:`~gmsfric.models.GMS` converted to SI.

    Raises
    ------
    UnitError
        A unit unknown or not of its quantity (before any work).
    """
    _, to_si = presliding_units(position_unit, force_unit, time_unit)
    t = as_array("time", t, min_len=10)
    x = as_array("position", position)
    F = as_array("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", F, "time", t.size)
    if n_blocks is not None and (int(n_blocks) != n_blocks or n_blocks < 1):
        raise InvalidInputError(f"`n_blocks` must be a positive integer, got {n_blocks}")
    if isinstance(max_blocks, bool) or not isinstance(max_blocks, (int, np.integer)) or max_blocks < 1:
        raise InvalidInputError(f"`max_blocks` must be a positive integer, got {max_blocks!r}")
    vc = build_virgin_curve(t, x, F, n_bins=n_bins, resolution=resolution)
    n_pts = vc.u_bin.size + 1
    candidates = [int(n_blocks)] if n_blocks is not None else list(range(1, max_blocks + 1))
    fits: dict[int, tuple] = {}
    bic: dict[int, float] = {}
    for nb in candidates:
        if n_pts < 2 * (nb + 1) + 1:
            if n_blocks is not None:
                raise IdentificationError(f"{n_pts - 1} virgin-curve bins cannot support {nb} blocks")
            break
        fits[nb] = _fit_virgin(vc, nb)
        rss = max(fits[nb][3], 1e-300)
        bic[nb] = n_pts * np.log(rss / n_pts) + 2 * nb * np.log(n_pts)
    nb = min(bic, key=bic.get)  # type: ignore[arg-type]
    k, d, vr, _ = fits[nb]
    w = k * d
    # standard errors of the virgin fit (log k, log d) -> k, w
    cov_v = covariance_from_jacobian(vr.jac, vr.fun)
    order = np.argsort(np.exp(vr.x[nb:]))
    info: dict[str, Any] = {"n_blocks": nb, "bic": {str(kk): float(v) for kk, v in bic.items()}, "virgin_bins": int(vc.u_bin.size), "turning_points": int(vc.turning_points.size)}
    info["virgin_fit"] = {"k": k.tolist(), "w": w.tolist(), "knots": d.tolist()}
    params: dict[str, tuple[float, float]]
    total = float(w.sum())
    if c is None:
        c = 1.0 / stribeck.vs if stribeck is not None else 1e3 * total / max(float(np.median(np.diff(t))) * 1e3, 1e-300)
    c_given = c is not None
    c = positive("c", c)
    level = {"stribeck": stribeck}
    if refine:
        cut = int(vc.turning_points[0])
        mask = np.zeros(t.size, dtype=bool)
        mask[cut:] = True
        # model input: the position lightly smoothed (cubic Savitzky-Golay over 1/100 of a
        # half-cycle keeps turning points exact and removes most of the quantisation staircase)
        win = int(np.median(np.diff(vc.turning_points)) / 100) | 1
        xs = savgol_filter(x, win, 3) if win >= 5 else x
        sigma_x = vc.resolution / np.sqrt(12.0) if resolution is None else resolution / np.sqrt(12.0)
        weight = np.ones(t.size)
        scale_f = max(float(np.std(F[mask])), 1e-300)

        with Progress("pre-sliding hysteresis fit", enabled=progress) as prog:

            def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
                kk, ww = np.exp(q[:nb]), np.exp(q[nb:])
                st_now = level["stribeck"]
                c_now = c if c_given or st_now is None else 1.0 / st_now.vs
                sim = simulate_friction(_make_gms(kk, ww, c_now, st_now, sigma, slip_law), t, xs)
                prog.update()
                return (sim[mask] - F[mask]) * weight[mask]

            q0 = np.concatenate((np.log(k), np.log(w)))
            bounds = (q0 - 8.0, q0 + 8.0)
            weight[:] = 1.0 / scale_f
            r = least_squares(resid, q0, bounds=bounds, method="trf", x_scale="jac", diff_step=1e-4, max_nfev=100 * (2 * nb + 1))
            # errors in variables (effective variance): a position error sigma_x moves the force
            # by the local stiffness dF/dx, large right after every reversal
            kk, ww = np.exp(r.x[:nb]), np.exp(r.x[nb:])
            sim = simulate_friction(_make_gms(kk, ww, c, stribeck, sigma, slip_law), t, xs)
            dxs = np.gradient(xs)
            k_total = float(kk.sum())
            with np.errstate(divide="ignore", invalid="ignore"):
                k_loc = np.where(np.abs(dxs) > 1e-6 * max(float(np.ptp(xs)), 1e-300), np.gradient(sim) / dxs, k_total)
            k_loc = np.clip(np.nan_to_num(k_loc, nan=k_total), 0.0, k_total)
            res0 = sim - F
            soft = mask & (k_loc <= np.median(k_loc[mask]))
            sigma_f = 1.4826 * float(np.median(np.abs(res0[soft] - np.median(res0[soft])))) if soft.any() else scale_f
            sigma_f = max(sigma_f, 1e-12 * scale_f)
            weight[:] = 1.0 / np.sqrt(sigma_f**2 + (k_loc * sigma_x) ** 2)
            r = least_squares(resid, r.x, bounds=bounds, method="trf", x_scale="jac", diff_step=1e-4, max_nfev=100 * (2 * nb + 1))
            kq, wq = np.exp(r.x[:nb]), np.exp(r.x[nb:])
            inflation = autocorrelation_inflation(r.fun)
            cov = covariance_from_jacobian(r.jac, r.fun) * inflation
            if stribeck is not None and stribeck_stderr:
                propagated = np.zeros_like(cov)
                for name in ("fc", "fs", "vs", "delta"):
                    se_p = float(stribeck_stderr.get(name, 0.0) or 0.0)
                    if not np.isfinite(se_p) or se_p <= 0:
                        continue
                    vals = {"fc": stribeck.fc, "fs": stribeck.fs, "vs": stribeck.vs, "delta": stribeck.delta}
                    vals[name] = vals[name] + se_p
                    try:
                        level["stribeck"] = Stribeck(**vals)
                    except InvalidInputError:
                        continue
                    rp = least_squares(resid, r.x, bounds=bounds, method="trf", x_scale="jac", diff_step=1e-4, max_nfev=10 * (2 * nb + 1))
                    shift = rp.x - r.x
                    propagated += np.outer(shift, shift)
                level["stribeck"] = stribeck
                cov = cov + propagated
                info["stribeck_propagated"] = True
        info["stderr_inflation"] = inflation
        info["force_noise"] = sigma_f
        se = np.sqrt(np.clip(np.diag(cov), 0, np.inf))
        se_k, se_w = kq * se[:nb], wq * se[nb:]
        # quantisation floor: each branch locates a knot d_i only to ~ resolution / sqrt(12);
        # averaged over the reversals, k_i = w_i / d_i cannot be known better than that
        n_rev = max(1, len(vc.turning_points) - 1)
        floor_k = kq * (sigma_x / (wq / kq)) / np.sqrt(n_rev)
        se_k = np.sqrt(se_k**2 + floor_k**2)
        order = np.argsort(wq / kq)
        # covariance of (k, w) from that of (log k, log w), with the quantisation floor on k
        cov_kw = transform_covariance(cov, np.diag(np.concatenate((kq, wq))))
        cov_kw[np.arange(nb), np.arange(nb)] += floor_k**2
        perm = np.concatenate((order, nb + order))
        cov_kw = cov_kw[np.ix_(perm, perm)]
        kq, wq, se_k, se_w = kq[order], wq[order], se_k[order], se_w[order]
        info["rms_residual"] = float(np.sqrt(np.mean((r.fun / weight[mask]) ** 2)))
        info["refined"] = True
    else:
        se = np.sqrt(np.clip(np.diag(cov_v), 0, np.inf))
        slk, sld = se[:nb][order], se[nb:][order]
        cov_kd = np.array([cov_v[i, nb + i] for i in range(nb)])[order]
        kq, wq = k, w
        se_k = k * slk
        se_w = w * np.sqrt(np.clip(slk**2 + sld**2 + 2 * cov_kd, 0, np.inf))
        # covariance of (k, w = k d) from that of (log k, log d), in the order of the sorted blocks
        k_u, w_u = np.exp(vr.x[:nb]), np.exp(vr.x[:nb] + vr.x[nb:])
        jac_kw = np.block([[np.diag(k_u), np.zeros((nb, nb))], [np.diag(w_u), np.diag(w_u)]])
        perm = np.concatenate((order, nb + order))
        cov_kw = transform_covariance(cov_v, jac_kw)[np.ix_(perm, perm)]
        info["refined"] = False
    params = {}
    for i in range(nb):
        params[f"k{i + 1}"] = (float(kq[i]), float(se_k[i]))
    for i in range(nb):
        params[f"w{i + 1}"] = (float(wq[i]), float(se_w[i]))
    units = {**{f"k{i + 1}": _units.ratio(force_unit, position_unit) for i in range(nb)}, **{f"w{i + 1}": force_unit for i in range(nb)}}
    info["knots"] = (wq / kq).tolist()
    info["break_force"] = float(wq.sum())
    info["c"] = c
    model = _make_gms(kq, wq, c, stribeck, sigma, slip_law)
    data = {"t": t, "x": x, "F": F, "virgin": vc, "virgin_k": k, "virgin_d": d, "stribeck": stribeck, "sigma": sigma, "slip_law": slip_law, "model": model,
            "position_unit": position_unit, "force_unit": force_unit, "time_unit": time_unit}
    return IdentificationResult("presliding", params, units, info, data=data,
                                model_object=_gms_si(kq, wq, c, stribeck, sigma, slip_law, to_si), covariance=(list(params), cov_kw))
