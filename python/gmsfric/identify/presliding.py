"""Pre-sliding blocks (paper Section 3.2, eq. 6, Figs. 6-8) from a virgin-curve test or from any
record with reversals.

N elasto-slip blocks (stiffness ``k_i``, break force ``w_i``, break displacement
``d_i = w_i / k_i``) give the force ``F = sum_i k_i z_i`` where ``z_i`` follows the position with
play ``d_i`` (``z_i <- clip(z_i + dx, -d_i, d_i)``).  For given break displacements the force is
*linear* in ``k``: every fit below optimises the ``d_i`` only and gets ``k`` (and a force offset)
by linear least squares (variable projection), so no start value of ``k`` is needed and the
solver cannot walk a block to zero stiffness.

Stages, each a function:

1. :func:`_record_si`: the record checked and converted to SI once (units never reach the fit).
2. :func:`estimate_resolution`, :func:`turning_points`.
3. :func:`build_virgin_curve`: the Masing branches, halved and shifted to the origin (the paper's
   construction), each used only as far as the previous branch reached.
4. :func:`_fit_virgin`: ``g(u) = sum_i k_i min(u, d_i)`` on the virgin points for N blocks, from
   several starts (dynamic-programming segmentation, log-spaced knots, the N-1 solution with one
   knot added, random knots); the best admissible fit (no zero, merged or out-of-range block).
5. :func:`_choose_block_count`: BIC on the virgin points; it compares fits of one data set, so it
   does not depend on the units (the record is in SI anyway).
6. :func:`_fit_hysteresis`: the simulated block force along the measured position fitted to the
   measured force (all samples from the first instant every block is certainly saturated, or from
   the start when the record is shown to start virgin); weights from the force noise and the
   position error times the local stiffness (errors in variables).
7. :func:`_polish_gms`: with a Stribeck level given, the GMS force (the level follows the
   velocity) refitted in ``(log k, log w)``.
8. :func:`_diagnose`: findings (knots outside the data, blocks the data do not determine, chi2).

Blocks are reported in order of break displacement (eq. 6's order).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares, nnls
from scipy.signal import savgol_coeffs, savgol_filter

from .. import curves
from .. import units as _units
from .._progress import Progress
from .._validate import measured_signal, positive, same_length
from ..batch import simulate_friction_batch
from ..errors import IdentificationError, InvalidInputError
from ..models import GMS, MaxwellSlip, Stribeck
from .diagnostics import Findings, check_chi2, check_stderr, emit
from .sampling import estimate_resolution, white_noise_level
from .results import IdentificationResult, autocorrelation_inflation, covariance_from_jacobian, transform_covariance

#: Adjacent break displacements closer than this ratio are one block (not identifiable apart).
MIN_KNOT_RATIO = 1.05

#: The block-count search tries this many counts beyond the best one found so far (each way).
SEARCH_BEYOND = 2


@dataclass
class VirginCurve:
    """Virgin-curve points from Masing branches and their log-binned averages (SI: m, N)."""

    u: NDArray[np.float64]
    g: NDArray[np.float64]
    u_bin: NDArray[np.float64]
    g_bin: NDArray[np.float64]
    se_bin: NDArray[np.float64]
    count_bin: NDArray[np.int64]
    turning_points: NDArray[np.int64]
    resolution: float
    branch: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    sample: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    force_noise: float = 0.0


@dataclass
class BlockFit:
    """Blocks from one fit: stiffness ``k``, break displacements ``d`` (sorted), the weighted
    residual sum of squares, whether every block is admissible, and why not."""

    k: NDArray[np.float64]
    d: NDArray[np.float64]
    rss: float
    admissible: bool
    reason: str = ""
    offset: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def w(self) -> NDArray[np.float64]:
        return self.k * self.d


# ----------------------------------------------------------------------------- 1. record


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


def _record_si(t: ArrayLike, position: ArrayLike, force: ArrayLike, f: Mapping[str, float]) -> tuple[NDArray[np.float64], ...]:
    t = measured_signal("time", t, min_len=10)
    x = measured_signal("position", position)
    F = measured_signal("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", F, "time", t.size)
    if np.any(np.diff(t) <= 0):
        raise InvalidInputError("`time` must increase strictly")
    _check_varies(x, F)
    return t * f["time"], x * f["position"], F * f["force"]


def _check_sign(vc: VirginCurve) -> None:
    """A virgin curve that falls (the force change opposes the motion after most reversals) is
    a force in the reaction convention: no block set has negative stiffness, so say so."""
    if vc.g_bin.size and np.mean(vc.g_bin < 0) > 0.75 and vc.g_bin[-1] < 0:
        raise IdentificationError("the force appears to have the opposite sign to the motion (after a reversal it changes against the "
                                  "new direction): friction opposes the motion, and gmsfric expects the force applied to the axis (the "
                                  "drive force, with the sign of the motion), not the friction's reaction on it; negate the force")


def _check_varies(x: NDArray[np.float64], F: NDArray[np.float64]) -> None:
    """A record whose position or force never changes has no hysteresis (and zero noise, which
    the fit's weights would divide by)."""
    for name, a in (("position", x), ("force", F)):
        if np.ptp(a) == 0:
            raise IdentificationError(f"the {name} never changes: no pre-sliding hysteresis to fit")


# ----------------------------------------------------------------------------- 2. resolution, reversals


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


def turning_points(x: NDArray[np.float64], resolution: float) -> list[int]:
    """Reversals of the position: a zig-zag with a 10-resolution threshold, repeated on a lightly
    smoothed signal, each placed in the middle of its (quantised) flat top."""
    thr = 10.0 * resolution
    turns = _zigzag(x, thr)
    if len(turns) < 2:
        return turns
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
    return refined


# ----------------------------------------------------------------------------- 3. virgin curve


def _masing_points(x: NDArray[np.float64], F: NDArray[np.float64], turns: list[int]) -> tuple[NDArray[np.float64], ...]:
    """Halved branches from every turning point, each kept while it has not passed the span of
    the previous monotone move (beyond it Masing no longer holds; within it, it holds for any
    earlier state of the blocks, so the record need not start virgin)."""
    half = max(1, int(np.median(np.diff(turns)) / 200)) if len(turns) > 1 else 1
    starts = [0] + turns
    ends = turns + [x.size - 1]
    us, gs, bs, ss = [], [], [], []
    for j, r in enumerate(turns):
        span_prev = abs(x[r] - x[starts[j]])
        end = ends[j + 1]
        Fr = float(np.mean(F[max(0, r - half) : r + half + 1]))
        idx = np.arange(r, end + 1)
        direction = np.sign(x[end] - x[r]) or 1.0
        du = direction * (x[idx] - x[r])
        ok = (du >= 0) & (du <= span_prev * (1 + 1e-9))
        us.append(du[ok] / 2)
        gs.append(direction * (F[idx][ok] - Fr) / 2)
        bs.append(np.full(int(ok.sum()), j))
        ss.append(idx[ok])
    return np.concatenate(us), np.concatenate(gs), np.concatenate(bs).astype(np.int64), np.concatenate(ss).astype(np.int64)


def _bin_virgin(u: NDArray[np.float64], g: NDArray[np.float64], n_bins: int, resolution: float) -> tuple[NDArray[np.float64], ...]:
    """Log-spaced bins of the virgin points (block break displacements span decades)."""
    pos = u > 0
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
        raise IdentificationError(f"only {len(ub)} populated bins on the virgin curve: need at least 6 (more reversals or a larger amplitude)")
    sb_arr = np.asarray(sb)
    floor = max(float(np.median(sb_arr)) * 0.1, 1e-12 * float(np.abs(gb).max()))
    return np.asarray(ub), np.asarray(gb), np.maximum(sb_arr, floor), np.asarray(cb)


def build_virgin_curve(
    t: ArrayLike,
    position: ArrayLike,
    force: ArrayLike,
    *,
    n_bins: int = 80,
    resolution: float | None = None,
) -> VirginCurve:
    """The virgin curve of a record with reversals by the Masing rule (halve, shift; see the
    module docstring), with log-binned averages.

    Parameters
    ----------
    t, position, force : array_like
        The record (any consistent units; the curve is in them).
    n_bins : int
        Log-spaced bins of ``u`` between the position resolution and the largest half-span.
    resolution : float, optional
        Position resolution (encoder quantum or noise level); estimated when not given.

    Raises
    ------
    IdentificationError
        Fewer than 3 reversals, or too few points on the curve.
    """
    t = measured_signal("time", t, min_len=10)
    x = measured_signal("position", position)
    F = measured_signal("force", force)
    same_length("position", x, "time", t.size)
    same_length("force", F, "time", t.size)
    _check_varies(x, F)
    if resolution is None:
        resolution = estimate_resolution(x)
    resolution = positive("resolution", resolution)
    turns = turning_points(x, resolution)
    if len(turns) < 3:
        raise IdentificationError(f"found {len(turns)} turning points of the position: need at least 3 (two full branches of a sinusoid test)")
    u, g, branch, sample = _masing_points(x, F, turns)
    if int((u > 0).sum()) < 20:
        raise IdentificationError("too few points on the virgin curve (are the amplitudes above the position resolution?)")
    ub, gb, sb, cb = _bin_virgin(u, g, n_bins, resolution)
    return VirginCurve(u, g, ub, gb, sb, cb, np.asarray(turns), float(resolution), branch, sample, white_noise_level(F))


def virgin_model(u: NDArray[np.float64], k: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sum_i k_i min(u, d_i)`` for ``u >= 0``: the virgin curve of blocks with knots ``d_i``
    (:func:`gmsfric.curves.virgin_curve` with break forces ``k_i d_i``)."""
    return curves.virgin_curve(u, k, k * d)


# ----------------------------------------------------------------------------- 4. virgin fit


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


def _dp_knots(vc: VirginCurve, n_blocks: int) -> NDArray[np.float64] | None:
    """Knots of the optimal piecewise-linear segmentation of the binned curve on log u."""
    x = vc.u_bin
    if x.size < 2 * (n_blocks + 1) + 1:
        return None
    cuts = _segment_dp(np.log(x), vc.g_bin, 1.0 / vc.se_bin**2, n_blocks + 1)
    return np.array([np.sqrt(x[c - 1] * x[c]) for c in cuts])


class _LinearBlocks:
    """Variable projection for a model ``y ~ A(d) k (+ offset)``: for knots ``d`` the stiffnesses
    (and offset) follow by linear least squares; ``k >= 0`` is enforced by NNLS when the plain
    solution has a negative stiffness."""

    def __init__(self, y: NDArray[np.float64], weight: NDArray[np.float64], offset: bool) -> None:
        self.y, self.weight, self.offset = y, weight, offset
        self.yw = y * weight

    def solve(self, A: NDArray[np.float64]) -> tuple[NDArray[np.float64], float, NDArray[np.float64]]:
        """``(k, offset, weighted residual)`` for the columns ``A`` (one per block)."""
        cols = np.column_stack([A, np.ones(A.shape[0])]) if self.offset else A
        Aw = cols * self.weight[:, None]
        nb = A.shape[1]
        # the least-squares problem reduced to its few columns (QR), so NNLS stays cheap
        if self.offset:
            # NNLS on k with a free offset: the offset as the difference of two non-negative parts
            Aw = np.column_stack([Aw, -Aw[:, -1]])
        q, R = np.linalg.qr(Aw)
        qty = q.T @ self.yw
        coef, *_ = np.linalg.lstsq(R[:, : nb + 1] if self.offset else R, qty, rcond=None)
        if np.any(coef[:nb] < 0):
            sol, _ = nnls(R, qty, maxiter=50 * R.shape[1])
            coef = np.concatenate([sol[:nb], [sol[nb] - sol[nb + 1]]]) if self.offset else sol
        r = (cols @ coef[: cols.shape[1]] - self.y) * self.weight
        return coef[:nb], float(coef[nb]) if self.offset else 0.0, r


def _admissible(k: NDArray[np.float64], d: NDArray[np.float64], lo: float, hi: float, resolution: float, beyond: bool = False) -> tuple[bool, str]:
    """A block set the data can determine: every stiffness positive, knots apart by at least
    ``MIN_KNOT_RATIO`` and a few resolutions, every knot inside ``(lo, hi)`` (a block that never
    breaks within the data, or breaks below the resolution, has no identifiable break force).
    ``beyond``: the last knot may sit at ``hi`` (the virgin curve ends before it, the force record
    does not)."""
    order = np.argsort(d)
    k, d = k[order], d[order]
    if np.any(k <= 1e-9 * max(float(k.max()), 1e-300)):
        return False, "a block with zero stiffness"
    if d.size > 1 and np.any((d[1:] / d[:-1] < MIN_KNOT_RATIO) | (np.diff(d) < 2 * resolution)):
        return False, "two blocks with the same break displacement"
    if d[0] <= max(lo * 1.001, 2.0 * resolution):
        return False, "a block breaking within two position resolutions"
    if d[-1] >= hi * 0.999 and not beyond:
        return False, "a block that does not break within the measured range"
    w = k * d
    if np.any(w < 1e-4 * w.sum()):
        return False, "a block with a negligible break force"
    return True, ""


def _virgin_points(vc: VirginCurve) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    """The virgin points used by the fits, their weights and the knot range ``(lo, hi)``."""
    keep = vc.u > 0
    u, g = vc.u[keep], vc.g[keep]
    # weights: force noise (halved, as g is) and the position error times the local slope
    sigma_f = max(vc.force_noise / 2.0, 1e-12 * float(np.ptp(g)))
    sigma_u = vc.resolution / np.sqrt(12.0) / np.sqrt(2.0)
    slope = np.interp(u, vc.u_bin, np.gradient(vc.g_bin, vc.u_bin))
    weight = 1.0 / np.sqrt(sigma_f**2 + (np.clip(slope, 0.0, None) * sigma_u) ** 2)
    lo = max(vc.resolution / 2.0, float(u.min()))
    hi = float(u.max())
    return u, g, weight, lo, hi


def _virgin_problem(vc: VirginCurve, n_fine: int = 400) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float, float]:
    """The virgin points averaged in fine log-spaced bins (weighted means; 2 % wide, so the kink
    of a knot inside a bin moves its mean by ~1e-4 of the knot): the fits run on these, the
    block count is judged on the points themselves."""
    u, g, weight, lo, hi = _virgin_points(vc)
    edges = np.geomspace(lo, hi * (1 + 1e-12), n_fine + 1)
    idx = np.clip(np.digitize(u, edges) - 1, 0, n_fine - 1)
    w2 = weight**2
    sw = np.bincount(idx, w2, n_fine)
    ok = sw > 0
    ub = np.bincount(idx, w2 * u, n_fine)[ok] / sw[ok]
    gb = np.bincount(idx, w2 * g, n_fine)[ok] / sw[ok]
    return ub, gb, np.sqrt(sw[ok]), lo, hi


def _vp_fit_virgin(u: NDArray[np.float64], lin: _LinearBlocks, d0: NDArray[np.float64], lo: float, hi: float, resolution: float,
                   beyond: bool = False) -> BlockFit:
    """One variable-projection fit of the virgin curve from knots ``d0``."""
    nb = d0.size
    cache: dict[bytes, Any] = {}

    def evaluate(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], float, NDArray[np.float64], NDArray[np.float64]]:
        key = theta.tobytes()
        if key not in cache:
            d = np.exp(theta)
            A = np.minimum(u[:, None], d[None, :])
            k, off, r = lin.solve(A)
            cache.clear()
            cache[key] = (k, off, r, A)
        return cache[key]

    def resid(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return evaluate(theta)[2]

    def jac(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        k, _, _, A = evaluate(theta)
        d = np.exp(theta)
        # d/dlog d_i of k_i min(u, d_i), with the linear part projected out (Kaufman)
        G = (u[:, None] > d[None, :]) * (k * d)[None, :] * lin.weight[:, None]
        Aw = A * lin.weight[:, None]
        q, _ = np.linalg.qr(Aw)
        return G - q @ (q.T @ G)  # type: ignore[no-any-return]

    blo, bhi = np.log(lo * 0.5), np.log(hi * 1.5)
    theta0 = np.clip(np.log(np.sort(d0)), blo + 1e-9, bhi - 1e-9)
    sol = least_squares(resid, theta0, jac=jac, bounds=(np.full(nb, blo), np.full(nb, bhi)), method="trf", x_scale=1.0, max_nfev=200)
    d = np.exp(sol.x)
    k, off, r, _ = evaluate(sol.x)
    order = np.argsort(d)
    ok, why = _admissible(k, d, lo, hi, resolution, beyond)
    fit = BlockFit(k[order], d[order], float(r @ r), ok, why, off)
    fit.extra["beyond"] = bool(d.max() >= hi * 0.999)
    return fit


def _virgin_starts(vc: VirginCurve, nb: int, lo: float, hi: float, previous: BlockFit | None, rng: np.random.Generator) -> list[NDArray[np.float64]]:
    starts: list[NDArray[np.float64]] = []
    dp = _dp_knots(vc, nb)
    if dp is not None:
        starts.append(dp)
    starts.append(np.geomspace(lo * 2.0, hi / 1.5, nb) if nb > 1 else np.array([np.sqrt(lo * hi)]))
    if previous is not None:
        # the N-1 solution with one knot added in every gap (and at both ends)
        edges = np.concatenate(([lo * 1.5], previous.d, [hi / 1.2]))
        for a, b in zip(edges[:-1], edges[1:]):
            starts.append(np.sort(np.concatenate((previous.d, [np.sqrt(a * b)]))))
    for _ in range(3):
        starts.append(np.sort(np.exp(rng.uniform(np.log(lo * 1.5), np.log(hi / 1.2), nb))))
    return starts


def _fit_virgin(vc: VirginCurve, n_blocks: int, previous: BlockFit | None = None, *, hi_force: float = 0.0, n_polish: int = 4,
                seed: int = 0) -> list[BlockFit]:
    """Fits of ``n_blocks`` blocks to the virgin points from several starts, best first (the
    admissible ones before the others).  ``hi_force``: the largest break displacement the force
    record can show (its largest half-swing); beyond the virgin curve's end, the last block may
    break there."""
    u, g, weight, lo, hi = _virgin_problem(vc)
    lin = _LinearBlocks(g, weight, offset=False)
    rng = np.random.default_rng(seed + 7919 * n_blocks)
    starts = _virgin_starts(vc, n_blocks, lo, hi, previous, rng)
    # rank the starts by their cost before polishing the most promising ones
    scored = []
    for d0 in starts:
        A = np.minimum(u[:, None], np.sort(d0)[None, :])
        _, _, r = lin.solve(A)
        scored.append((float(r @ r), d0))
    scored.sort(key=lambda s: s[0])
    beyond = hi_force > 1.05 * hi
    fits = [_vp_fit_virgin(u, lin, d0, lo, hi, vc.resolution, beyond) for _, d0 in scored[:n_polish]]
    up, gp, wp, _, _ = _virgin_points(vc)
    for f in fits:
        r = (virgin_model(up, f.k, f.d) - gp) * wp
        f.extra["rss_points"] = float(r @ r)
    fits.sort(key=lambda f: (not f.admissible, f.rss))
    return fits


# ----------------------------------------------------------------------------- 5. block count


def _bic(fit: BlockFit, n: int, n_eff: float) -> float:
    """Schwarz criterion with an effective sample size (correlated residuals): ``n_eff ln(RSS/n)
    + 2N ln(n_eff)``.  Only differences between candidates matter, and those are free of the
    units of the data."""
    rss = fit.extra.get("rss_points", fit.rss)
    return n_eff * np.log(max(rss, 1e-300) / n) + 2 * fit.k.size * np.log(n_eff)


def _virgin_covariance(vc: VirginCurve, fit: BlockFit) -> tuple[NDArray[np.float64], float, float]:
    """Covariance of ``(log k, log d)`` of a virgin-curve fit from the points' Jacobian, times the
    residual's autocorrelation time; returns it, that time and chi2/dof."""
    u, g, weight, _, _ = _virgin_points(vc)
    A = np.minimum(u[:, None], fit.d[None, :])
    sgn = (u[:, None] > fit.d[None, :]).astype(float)
    r = (A @ fit.k - g) * weight
    J = np.column_stack([A * fit.k[None, :], sgn * (fit.k * fit.d)[None, :]]) * weight[:, None]
    order = np.argsort(vc.sample[vc.u > 0], kind="stable")
    inflation = autocorrelation_inflation(r[order])
    return covariance_from_jacobian(J, r) * inflation, inflation, float(r @ r) / max(r.size - J.shape[1], 1)


def _significant(vc: VirginCurve, fit: BlockFit, z_min: float = 2.0) -> bool:
    """Every block's stiffness and break force at least ``z_min`` standard errors from zero."""
    cov, _, _ = _virgin_covariance(vc, fit)
    nb = fit.k.size
    var_lk = np.diag(cov)[:nb]
    var_lw = var_lk + np.diag(cov)[nb:] + 2 * np.diag(cov[:nb, nb:])
    se = np.sqrt(np.clip(np.concatenate((var_lk, var_lw)), 0, np.inf))
    return bool(np.all(np.isfinite(se)) and np.all(se <= 1.0 / z_min))


def _rank_block_counts(best: dict[int, BlockFit], vc: VirginCurve, n: int, n_eff: float) -> tuple[list[int], dict[int, float]]:
    """Candidate counts, best BIC first among the admissible fits whose blocks are all
    significant (then the admissible others)."""
    bic = {nb: _bic(f, n, n_eff) for nb, f in best.items()}
    admissible = [nb for nb, f in best.items() if f.admissible]
    if not admissible:
        raise IdentificationError("no admissible block set: every fit has a zero, merged or out-of-range block (more reversals or larger amplitudes?)")
    sig = {nb: _significant(vc, best[nb]) for nb in admissible}
    return sorted(admissible, key=lambda nb: (not sig[nb], bic[nb])), bic


# ----------------------------------------------------------------------------- 6. hysteresis fit


def _play(t: NDArray[np.float64], x: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """Play (elasto-slip) operator outputs ``z_i`` of half-widths ``d_i`` along ``x`` from a
    virgin state, one column per block (unit-stiffness Maxwell-slip blocks on the core)."""
    models = [MaxwellSlip([1.0], [float(di)]) for di in d]
    return simulate_friction_batch(models, t, x, threads=1, progress=False).T  # type: ignore[no-any-return]


def _saturation_sign(z: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """``dz_i/dd_i``: the sign of the last saturation of each block (its spring then sits at
    ``±d_i`` plus the travel since), 0 before its first one."""
    sat = np.abs(z) >= d[None, :] * (1 - 1e-9)
    idx = np.where(sat, np.arange(z.shape[0])[:, None], -1)
    last = np.maximum.accumulate(idx, axis=0)
    sign = np.sign(np.take_along_axis(z, np.maximum(last, 0), axis=0))
    return np.where(last >= 0, sign, 0.0)


def _largest_half_swing(x: NDArray[np.float64], turns: list[int]) -> float:
    """Half the largest monotone move: a block breaks in the record only below it."""
    idx = [0] + list(turns) + [x.size - 1]
    return 0.5 * float(np.max(np.abs(np.diff(x[idx]))))


def _known_state_start(x: NDArray[np.float64], turns: list[int], d_max: float) -> int:
    """First sample after which every block's state is known whatever it was at the start: the
    end of the first monotone move longer than twice the largest break displacement."""
    starts = [0] + list(turns)
    ends = list(turns) + [x.size - 1]
    for a, b in zip(starts, ends):
        travel = np.abs(x[a : b + 1] - x[a])
        hit = np.flatnonzero(travel >= 2.0 * d_max * 1.02)
        if hit.size:
            return a + int(hit[0])
    return x.size


@dataclass
class _HysteresisData:
    t: NDArray[np.float64]
    x: NDArray[np.float64]          # smoothed position, the model's input
    F: NDArray[np.float64]
    sigma_x: NDArray[np.float64]    # position error of the model input, per sample
    sigma_f: float                  # force noise
    sigma_reversal: float = 0.0     # position error at a reversal


def _smoothed_position(x: NDArray[np.float64], turns: NDArray[np.int64], resolution: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The position lightly smoothed (cubic Savitzky-Golay over 1/100 of a half-cycle keeps the
    reversals and removes most of the quantisation staircase) and the error left at each sample:
    averaging helps only as far as the window spans several encoder counts (a slow staircase
    keeps its full quantisation error)."""
    win = int(np.median(np.diff(turns)) / 100) | 1 if len(turns) > 1 else 1
    sigma_q = resolution / np.sqrt(12.0)
    # a record moving many counts a sample has no staircase to smooth; smoothing would only
    # round its reversals (a triangle wave's corner by several samples' travel)
    if win < 5 or float(np.median(np.abs(np.diff(x)))) > 10.0 * resolution:
        return x, np.full(x.size, sigma_q)
    gain = float(np.sqrt(np.sum(savgol_coeffs(win, 3) ** 2)))
    xs = savgol_filter(x, win, 3)
    h = win // 2
    travel = np.abs(np.concatenate((xs[2 * h:] - xs[:-2 * h], np.zeros(2 * h))))
    travel = np.roll(travel, h)
    counts = np.maximum(travel / resolution, 1.0)
    return xs, sigma_q * np.maximum(gain, 1.0 / np.sqrt(counts))


def _reversal_error(x: NDArray[np.float64], resolution: float) -> float:
    """Position error at a reversal: the quantisation error (smoothing does not reduce it on a
    flat top, where every sample has the same count) or the white noise, whichever dominates."""
    return max(resolution / np.sqrt(12.0), white_noise_level(x) / 3.0)


def _hysteresis_weight(z: NDArray[np.float64], k: NDArray[np.float64], d: NDArray[np.float64], data: _HysteresisData) -> NDArray[np.float64]:
    """``1/sqrt(sigma_F^2 + (k_loc sigma_x)^2)``: a position error moves the force by the local
    stiffness, the sum of the sticking blocks' stiffnesses (large right after a reversal)."""
    sticking = np.abs(z) < d[None, :] * (1 - 1e-9)
    k_loc = sticking @ k
    return 1.0 / np.sqrt(data.sigma_f**2 + (k_loc * data.sigma_x) ** 2)


def _vp_fit_hysteresis(data: _HysteresisData, d0: NDArray[np.float64], k0: NDArray[np.float64], mask: NDArray[np.bool_], lo: float, hi: float,
                       resolution: float, prog: Progress | None, max_nfev: int = 60) -> BlockFit:
    """Knots fitted to the measured force (variable projection; weights from the start blocks)."""
    nb = d0.size
    z0 = _play(data.t, data.x, d0)
    weight = _hysteresis_weight(z0, k0, d0, data)[mask]
    lin = _LinearBlocks(data.F[mask], weight, offset=True)
    cache: dict[bytes, Any] = {}

    def evaluate(theta: NDArray[np.float64]) -> Any:
        key = theta.tobytes()
        if key not in cache:
            d = np.exp(theta)
            z = _play(data.t, data.x, d)
            k, off, r = lin.solve(z[mask])
            cache.clear()
            cache[key] = (k, off, r, z)
            if prog is not None:
                prog.update()
        return cache[key]

    def resid(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        return evaluate(theta)[2]  # type: ignore[no-any-return]

    def jac(theta: NDArray[np.float64]) -> NDArray[np.float64]:
        k, _, _, z = evaluate(theta)
        d = np.exp(theta)
        G = (_saturation_sign(z, d)[mask] * (k * d)[None, :]) * weight[:, None]
        Aw = np.column_stack([z[mask], np.ones(int(mask.sum()))]) * weight[:, None]
        q, _ = np.linalg.qr(Aw)
        return G - q @ (q.T @ G)  # type: ignore[no-any-return]

    blo, bhi = np.log(lo * 0.5), np.log(hi * 1.5)
    theta0 = np.clip(np.log(np.sort(d0)), blo + 1e-9, bhi - 1e-9)
    sol = least_squares(resid, theta0, jac=jac, bounds=(np.full(nb, blo), np.full(nb, bhi)), method="trf", x_scale=1.0, max_nfev=max_nfev)
    d = np.exp(sol.x)
    k, off, r, z = evaluate(sol.x)
    order = np.argsort(d)
    ok, why = _admissible(k, d, lo, hi, resolution)
    fit = BlockFit(k[order], d[order], float(r @ r), ok, why, off)
    fit.extra = {"weight": weight, "residual": r, "z": z[:, order]}
    return fit


def _fit_hysteresis(data: _HysteresisData, start: BlockFit, others: list[BlockFit], turns: list[int], lo: float, hi: float, resolution: float,
                    progress: bool) -> tuple[BlockFit, NDArray[np.bool_], bool]:
    """The force fit over the whole record if it starts virgin, else over the samples whose block
    state is known (every block saturated once); returns the fit, the samples used and whether
    the virgin start was accepted.

    A virgin start is accepted when the fit over the whole record explains the part before the
    known-state sample as well as the rest (a random initial state leaves a force error of the
    order of a break force there, that no block set fits)."""
    n = data.t.size
    cands = [start] + others
    if start.extra.get("beyond"):
        # the last block breaks beyond the virgin curve: start it at a few places up to the
        # largest half-swing of the record
        for dn in np.geomspace(start.d[-1], 0.9 * hi, 4)[1:]:
            cands.append(BlockFit(start.k, np.concatenate((start.d[:-1], [dn])), start.rss, True))
    min_samples = 10 * (2 * start.k.size + 1)

    def best_of(mask: NDArray[np.bool_], prog: Progress) -> BlockFit:
        best = None
        for cand in cands:
            fit = _vp_fit_hysteresis(data, cand.d, cand.k, mask, lo, hi, resolution, prog)
            if best is None or (fit.admissible, -fit.rss) > (best.admissible, -best.rss):
                best = fit
        assert best is not None
        return best

    def known_from(fit: BlockFit) -> int:
        return min(_known_state_start(data.x, turns, float(fit.d.max())), n - min_samples)

    with Progress("pre-sliding hysteresis fit", enabled=progress) as prog:
        whole = np.ones(n, dtype=bool)
        best = best_of(whole, prog)
        s0 = known_from(best)
        virgin = True
        if s0 > 0:
            r = best.extra["residual"]
            early, late = float(np.mean(r[:s0] ** 2)), float(np.mean(r[s0:] ** 2))
            virgin = early <= 2.0 * late + 1.0
        mask = whole
        if not virgin:
            mask = np.zeros(n, dtype=bool)
            mask[s0:] = True
            best = best_of(mask, prog)
            s1 = known_from(best)
            if s1 > s0:
                # the fitted largest block breaks later than the start's: its state is known later
                mask[:] = False
                mask[s1:] = True
                best = _vp_fit_hysteresis(data, best.d, best.k, mask, lo, hi, resolution, prog)
        # the weights depend on the blocks: once more with the fitted ones
        best = _vp_fit_hysteresis(data, best.d, best.k, mask, lo, hi, resolution, prog, max_nfev=30)
    return best, mask, virgin


def _reversal_groups(x: NDArray[np.float64], samples: NDArray[np.int64], resolution: float) -> NDArray[np.int64]:
    """Group id of each sample by its measured position: reversals at the same encoder count
    share one quantisation error (a repeated sinusoid reverses at the same counts every cycle)."""
    vals = x[samples]
    order = np.argsort(vals)
    ids = np.zeros(vals.size, dtype=np.int64)
    if vals.size:
        ids[order] = np.cumsum(np.concatenate(([0], np.diff(vals[order]) > 0.5 * resolution)))
    return ids


def _hysteresis_covariance(fit: BlockFit, mask: NDArray[np.bool_], x: NDArray[np.float64], resolution: float,
                           sigma_reversal: float) -> tuple[NDArray[np.float64], NDArray[np.float64], float, float]:
    """Covariance of ``(log k, log d, offset)`` of the force fit; returns it, the residual's
    integrated autocorrelation time and chi2/dof.  Returns the two parts of the covariance
    (Jacobian, reversal errors), the autocorrelation time and chi2/dof.

    Two parts: the Jacobian covariance times the autocorrelation time (force noise and the
    position error of each sample, which the weights carry), and the effect of the position error
    at the reversals.  A sticking block's spring is the travel since it last slipped, so the
    error of that one sample (the reversal) moves the model force over the whole stick phase; the
    fit does not average it out like white noise (sandwich term, reversals at the same count
    sharing one error)."""
    z_all = fit.extra["z"]
    z = z_all[mask]
    wgt, r = fit.extra["weight"], fit.extra["residual"]
    k, d = fit.k, fit.d
    sgn = _saturation_sign(z_all, d)[mask]
    J = np.column_stack([z * k[None, :], sgn * (k * d)[None, :], np.ones(z.shape[0])]) * wgt[:, None]
    inflation = autocorrelation_inflation(r)
    dof = max(r.size - J.shape[1], 1)
    chi2_dof = float(r @ r) / dof
    cov = covariance_from_jacobian(J, r) * inflation
    if sigma_reversal <= 0 or not np.all(np.isfinite(np.diag(cov))):
        return cov, np.zeros_like(cov), inflation, chi2_dof
    # the sample where each block last left saturation, for every sticking sample
    sat = np.abs(z_all) >= d[None, :] * (1 - 1e-9)
    last = np.maximum.accumulate(np.where(sat, np.arange(z_all.shape[0])[:, None], -1), axis=0)[mask]
    sticking = (~sat[mask]) & (last >= 0)
    rows, blocks = np.nonzero(sticking)
    exits = last[rows, blocks]
    uniq, inverse = np.unique(exits, return_inverse=True)
    group = _reversal_groups(x, uniq, resolution)[inverse]
    # d(weighted residual)/d(error at the reversal) = -k_i w_t for each sticking sample
    contrib = (J[rows] * (wgt[rows] * k[blocks])[:, None])
    B = np.zeros((J.shape[1], int(group.max()) + 1 if group.size else 0))
    for j in range(J.shape[1]):
        B[j] = np.bincount(group, contrib[:, j], B.shape[1])
    A = covariance_from_jacobian(J, np.ones(J.shape[0]) * np.sqrt(max(J.shape[0] - J.shape[1], 1) / J.shape[0]))
    # covariance_from_jacobian(J, r) = s^2 (J^T J)^-1; with |r|^2 = dof it is (J^T J)^-1
    cov_rev = A @ B @ B.T @ A * sigma_reversal**2
    return cov, cov_rev, inflation, chi2_dof


# ----------------------------------------------------------------------------- 7. GMS polish


#: A slipping block without a Stribeck curve relaxes to its level within this fraction of the
#: smallest break displacement (at the record's top speed with the time law): the Maxwell-slip
#: limit, a property of the contact and not of the logging rate.
FAST_SLIP_FRACTION = 0.1


def _fast_slip(fit: BlockFit, t: NDArray[np.float64], x: NDArray[np.float64], slip_law: str) -> float:
    """Default GMS attraction ``c`` (SI) when no Stribeck curve gives one: fast against the
    smallest fitted break displacement, so the GMS behaves as the Maxwell-slip blocks fitted.
    Derived from the record's motion, never from its sample period (a record decimated 4x must
    give the same model)."""
    relax = FAST_SLIP_FRACTION * float(np.min(fit.d))  # relaxation distance (m)
    if slip_law == "displacement":
        return 1.0 / relax  # rate c |v|: relaxes over 1/c of sliding
    speed = np.abs(np.diff(x)) / np.diff(t)
    top = float(np.percentile(speed, 99)) if speed.size else 0.0
    top = top if top > 0 else float(np.ptp(x)) / max(float(t[-1] - t[0]), np.finfo(float).tiny)
    # time law: rate c / s(v) with s ~ sum(w); at the top speed it relaxes over ``relax``
    return float(fit.w.sum()) * top / relax


def _make_gms(k: NDArray[np.float64], w: NDArray[np.float64], c: float, stribeck: Stribeck | None, sigma: float, slip_law: str) -> GMS:
    return GMS.from_break_forces(k, w, c, stribeck=stribeck, sigma=sigma, slip_law=slip_law, scale="sum")  # type: ignore[arg-type]


def _polish_gms(data: _HysteresisData, fit: BlockFit, mask: NDArray[np.bool_], *, c: float, stribeck: Stribeck, sigma: float, slip_law: str,
                stribeck_stderr: Mapping[str, float] | None, progress: bool) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], dict[str, Any]]:
    """``(log k, log w, offset)`` refitted with the GMS force (the break level follows the
    Stribeck curve of the velocity); the Jacobian's simulations run as one batch.  Returns k, w,
    the covariance of ``(log k, log w, offset)`` and info."""
    nb = fit.k.size
    weight = fit.extra["weight"]
    Fm = data.F[mask]
    level = {"stribeck": stribeck}
    step = 1e-4

    def forces(qs: list[NDArray[np.float64]]) -> NDArray[np.float64]:
        models = [_make_gms(np.exp(q[:nb]), np.exp(q[nb:2 * nb]), c, level["stribeck"], sigma, slip_law) for q in qs]
        return simulate_friction_batch(models, data.t, data.x, threads=1, progress=False)[:, mask]

    with Progress("pre-sliding GMS refinement", enabled=progress) as prog:

        def resid(q: NDArray[np.float64]) -> NDArray[np.float64]:
            prog.update()
            return (forces([q])[0] + q[-1] - Fm) * weight  # type: ignore[no-any-return]

        def jac(q: NDArray[np.float64]) -> NDArray[np.float64]:
            qs = []
            for i in range(2 * nb):
                qi = q.copy()
                qi[i] += step
                qs.append(qi)
            sims = forces([q] + qs)
            cols = [(sims[i + 1] - sims[0]) / step for i in range(2 * nb)] + [np.ones(Fm.size)]
            return np.column_stack(cols) * weight[:, None]

        q0 = np.concatenate((np.log(fit.k), np.log(fit.w), [fit.offset]))
        lo = np.concatenate((q0[:-1] - 3.0, [-np.inf]))
        hi = np.concatenate((q0[:-1] + 3.0, [np.inf]))
        r = least_squares(resid, q0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=40)
        inflation = autocorrelation_inflation(r.fun)
        cov = covariance_from_jacobian(r.jac, r.fun) * inflation
        info: dict[str, Any] = {"stderr_inflation": inflation, "chi2_dof": float(r.fun @ r.fun) / max(r.fun.size - q0.size, 1)}
        if stribeck_stderr:
            # first-order propagation of the Stribeck curve's uncertainty: refit with each of
            # fc fs vs delta moved by one standard error
            propagated = np.zeros_like(cov)
            vals = {"fc": stribeck.fc, "fs": stribeck.fs, "vs": stribeck.vs, "delta": stribeck.delta}
            for name in ("fc", "fs", "vs", "delta"):
                se_p = float(stribeck_stderr.get(name, 0.0) or 0.0)
                if not np.isfinite(se_p) or se_p <= 0:
                    continue
                moved = dict(vals)
                moved[name] = vals[name] + se_p
                try:
                    level["stribeck"] = Stribeck(**moved)
                except InvalidInputError:
                    continue
                rp = least_squares(resid, r.x, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac", max_nfev=8)
                shift = rp.x - r.x
                propagated += np.outer(shift, shift)
            level["stribeck"] = stribeck
            cov = cov + propagated
            info["stribeck_propagated"] = True
    return np.exp(r.x[:nb]), np.exp(r.x[nb:2 * nb]), cov, {**info, "offset": float(r.x[-1]), "residual": r.fun}


# ----------------------------------------------------------------------------- 8. diagnostics


def _diagnose(findings: Findings, fit: BlockFit, vc: VirginCurve, params_si: Mapping[str, tuple[float, float]], chi2_dof: float, dof: int,
              hi: float, break_steps: NDArray[np.float64] | None = None) -> None:
    nb = fit.k.size
    if not fit.admissible:
        findings.add("degenerate", f"{nb} blocks: {fit.reason}; fewer blocks describe these data", None)
    if fit.d[-1] > 0.8 * hi:
        findings.add("coverage", f"block {nb} breaks at {fit.d[-1]:.3g} m, near the largest half-swing {hi:.3g} m of the data: "
                                 "its break force is poorly determined (a larger amplitude breaks every block clearly)", f"w{nb}")
    if fit.d[0] < 5 * vc.resolution:
        findings.add("coverage", f"block 1 breaks at {fit.d[0]:.3g} m, within 5 position resolutions ({vc.resolution:.3g} m): "
                                 "its stiffness is poorly determined", "k1")
    for i, step in enumerate(() if break_steps is None else break_steps):
        if fit.d[i] < step:
            findings.add("coverage", f"block {i + 1} breaks at {fit.d[i]:.3g} m, less than the position moves in one sample where it breaks "
                                     f"({step:.3g} m): the record cannot resolve it (it may stand for several blocks; sample faster or "
                                     "move slower)", f"k{i + 1}")
    check_stderr(findings, params_si)
    check_chi2(findings, chi2_dof * dof, dof, what=" of the force fit")


def _break_steps(t: NDArray[np.float64], x: NDArray[np.float64], d: NDArray[np.float64]) -> NDArray[np.float64]:
    """The position change per sample at the instants each block breaks (median over its
    breaks; 0 for a block that never breaks): a block breaking within one such step is not
    resolved by the sampling, whatever the encoder."""
    z = _play(t, x, d)
    sat = np.abs(z) >= d[None, :] * (1 - 1e-9)
    onset = sat[1:] & ~sat[:-1]
    dx = np.abs(np.diff(x))
    out = np.zeros(d.size)
    for i in range(d.size):
        at = np.flatnonzero(onset[:, i])
        if at.size:
            out[i] = float(np.median(dx[at]))
    return out


# ----------------------------------------------------------------------------- the identifier


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
    """Identify the blocks ``k_i`` (force/position) and ``w_i`` (force) from a record with
    reversals: a virgin-curve test (small and large sinusoids) or any hysteresis record (see the
    module docstring).

    Parameters
    ----------
    t, position, force : array_like
        The record.  It need not start virgin: the force fit uses the samples from the first
        instant every block is certainly saturated, and the start too when the record is shown
        to start virgin.
    n_blocks : int, optional
        Number of blocks; chosen by BIC over ``1..max_blocks`` when not given.
    max_blocks : int
        Largest number of blocks tried by BIC (>= 1).
    stribeck : Stribeck, optional
        Shape of the sliding level (e.g. from the static-map fit), in the data's units; it is
        rescaled so that ``s(0) = sum(w)`` (eq. 6) and the blocks are refitted with the GMS
        force.  Default: a constant level (Maxwell-slip blocks).
    c : float, optional
        GMS attraction parameter, in the data's units; default ``1 / vs`` of ``stribeck`` (the
        paper's statement) or, without ``stribeck``, fast: a slipping block relaxes within a tenth
        of the smallest break displacement (at the record's top speed with the time law), so the
        GMS acts as the fitted Maxwell-slip blocks whatever the sample rate.
    sigma : float
        Viscous coefficient of the GMS (data units).
    slip_law : {"time", "displacement"}
        GMS slip law.
    stribeck_stderr : mapping, optional
        Standard errors of ``stribeck``'s ``fc, fs, vs, delta``: their effect on the blocks is
        added to the covariance (first-order propagation).
    refine : bool
        Fit the simulated force to the measured force (else stop at the virgin-curve fit).
    n_bins : int
        Log-spaced bins of the virgin curve (starts of the knot search, figures).
    resolution : float, optional
        Position resolution in the data's unit; estimated when not given.
    position_unit, force_unit, time_unit : str
        Units of the data (any :mod:`gmsfric.units` reads; a rotary axis gives ``rad`` and
        ``N m``).  The record is converted to SI before anything else; the parameters are
        reported in these units, ``model_object`` is in SI.

    Returns
    -------
    IdentificationResult
        ``model="presliding"``, parameters ``k1..kN`` and ``w1..wN``; ``model_object`` the
        :class:`~gmsfric.models.GMS` in SI.

    Raises
    ------
    InvalidInputError
        Bad arguments (``n_blocks`` or ``max_blocks`` not a positive integer, ...), before any work.
    UnitError
        A unit unknown or not of its quantity (before any work).
    IdentificationError
        Too few reversals, or no block set the data determine (with ``n_blocks``: the data do not
        support that many blocks).
    """
    rotary, to_si = presliding_units(position_unit, force_unit, time_unit)
    if n_blocks is not None and (isinstance(n_blocks, bool) or int(n_blocks) != n_blocks or n_blocks < 1):
        raise InvalidInputError(f"`n_blocks` must be a positive integer, got {n_blocks!r}")
    if isinstance(max_blocks, bool) or not isinstance(max_blocks, (int, np.integer)) or max_blocks < 1:
        raise InvalidInputError(f"`max_blocks` must be a positive integer, got {max_blocks!r}")
    if isinstance(n_bins, bool) or not isinstance(n_bins, (int, np.integer)) or n_bins < 8:
        raise InvalidInputError(f"`n_bins` must be an integer >= 8, got {n_bins!r}")
    if slip_law not in ("time", "displacement"):
        raise InvalidInputError(f"`slip_law` must be 'time' or 'displacement', got {slip_law!r}")
    kx, kf, kt = to_si["position"], to_si["force"], to_si["time"]
    t_si, x_si, F_si = _record_si(t, position, force, to_si)
    st_si = None if stribeck is None else Stribeck(stribeck.fc * kf, stribeck.fs * kf, stribeck.vs * kx / kt, stribeck.delta)
    st_se_si = None if stribeck_stderr is None else {
        n: float(v) * {"fc": kf, "fs": kf, "vs": kx / kt, "delta": 1.0}[n] for n, v in stribeck_stderr.items() if n in ("fc", "fs", "vs", "delta") and v is not None}
    sigma_si = float(sigma) * kf * kt / kx
    res_si = None if resolution is None else positive("resolution", resolution) * kx
    c_si = None if c is None else positive("c", c) * (kf / kt if slip_law == "time" else 1.0 / kx)

    # 2-3. reversals and the virgin curve
    vc = build_virgin_curve(t_si, x_si, F_si, n_bins=n_bins, resolution=res_si)
    _check_sign(vc)
    _, _, _, lo, hi = _virgin_points(vc)
    hi_force = max(_largest_half_swing(x_si, list(vc.turning_points)), hi)

    # 4-5. virgin fits of each candidate count; the counts ranked by BIC
    fits, order, bic = _virgin_stage(vc, n_blocks, int(max_blocks), hi_force)
    data = None
    if refine:
        xs, sigma_x = _smoothed_position(x_si, vc.turning_points, vc.resolution)
        data = _HysteresisData(t_si, xs, F_si, sigma_x, max(vc.force_noise, 1e-9 * float(np.ptp(F_si))), _reversal_error(x_si, vc.resolution))

    # 6. the force fit of the best count whose blocks the whole record supports
    if data is None:
        nb = next((n for n in order if any(f.admissible for f in fits[n])), 0)
        if not nb:
            raise IdentificationError(f"the virgin curve does not support {order[0]} blocks: {fits[order[0]][0].reason}")
        vfit = next(f for f in fits[nb] if f.admissible)
        force_bic: dict[int, float] = {}
    else:
        nb, vfit, fit, mask, virgin, force_bic = _force_stage(data, vc, fits, order, lo, hi_force, n_blocks is None, progress)
    info: dict[str, Any] = {"n_blocks": nb, "bic": {str(k): float(v) for k, v in bic.items()}, "virgin_bins": int(vc.u_bin.size),
                            "turning_points": int(vc.turning_points.size), "virgin_fit": {"k": vfit.k.tolist(), "w": vfit.w.tolist(), "knots": vfit.d.tolist()}}
    if force_bic:
        info["bic_force"] = {str(k): float(v) for k, v in force_bic.items()}
    if c_si is None:
        c_si = 1.0 / st_si.vs if st_si is not None else _fast_slip(vfit, t_si, x_si, slip_law)

    if data is not None:
        cov_q, cov_rev, inflation, chi2_dof = _hysteresis_covariance(fit, mask, data.x, vc.resolution, data.sigma_reversal)
        k_si, w_si, cov_kw = fit.k, fit.w, _kw_covariance(cov_q + cov_rev, fit.k, fit.w, log_w=False)
        offset = fit.offset
        if st_si is not None:
            # 7. the GMS level follows the Stribeck curve: refit with it
            k_si, w_si, cov_p, pinfo = _polish_gms(data, fit, mask, c=c_si, stribeck=st_si, sigma=sigma_si, slip_law=slip_law,
                                                   stribeck_stderr=st_se_si, progress=progress)
            inflation, chi2_dof, offset = pinfo["stderr_inflation"], pinfo["chi2_dof"], pinfo["offset"]
            if pinfo.get("stribeck_propagated"):
                info["stribeck_propagated"] = True
            # the reversal errors act on the GMS as on the blocks: (log k, log d) -> (log k, log w)
            T = np.eye(2 * nb + 1)
            T[nb:2 * nb, :nb] = np.eye(nb)
            cov_kw = _kw_covariance(cov_p + T @ cov_rev @ T.T, k_si, w_si, log_w=True)
            o = np.argsort(w_si / k_si)
            perm = np.concatenate((o, nb + o))
            k_si, w_si, cov_kw = k_si[o], w_si[o], cov_kw[np.ix_(perm, perm)]
        dof = max(int(mask.sum()) - (2 * nb + 1), 1)
        info.update(stderr_inflation=inflation, chi2_dof=chi2_dof, force_offset=offset / kf, samples_fitted=int(mask.sum()), virgin_start=virgin,
                    force_noise=data.sigma_f / kf, rms_residual=float(np.sqrt(np.mean((fit.extra["residual"] / fit.extra["weight"]) ** 2))) / kf,
                    refined=True)
        final = BlockFit(k_si, w_si / k_si, fit.rss, fit.admissible, fit.reason, offset)
    else:
        cov_q, inflation, chi2_dof = _virgin_covariance(vc, vfit)
        k_si, w_si, cov_kw = vfit.k, vfit.w, _kw_covariance(cov_q, vfit.k, vfit.w, log_w=False)
        dof = max(int((vc.u > 0).sum()) - 2 * nb, 1)
        info.update(stderr_inflation=inflation, chi2_dof=chi2_dof, refined=False)
        final = vfit

    # 8. findings, and the report in the data's units (the edge); the model object stays in SI
    model = _make_gms(k_si, w_si, c_si, st_si, sigma_si, slip_law)
    se_si = np.sqrt(np.clip(np.diag(cov_kw), 0, np.inf))
    params_si = {f"k{i + 1}": (float(k_si[i]), float(se_si[i])) for i in range(nb)}
    params_si.update({f"w{i + 1}": (float(w_si[i]), float(se_si[nb + i])) for i in range(nb)})
    findings = Findings()
    _diagnose(findings, final, vc, params_si, chi2_dof, dof, hi_force, _break_steps(t_si, x_si, w_si / k_si))
    scale = np.concatenate((np.full(nb, kx / kf), np.full(nb, 1.0 / kf)))
    params = {name: (v * f, e * f) for (name, (v, e)), f in zip(params_si.items(), scale)}
    units = {**{f"k{i + 1}": _units.ratio(force_unit, position_unit) for i in range(nb)}, **{f"w{i + 1}": force_unit for i in range(nb)}}
    info["knots"] = (w_si / k_si / kx).tolist()
    info["break_force"] = float(w_si.sum() / kf)
    info["c"] = c_si / (kf / kt if slip_law == "time" else 1.0 / kx)
    data_out = {"t": t_si, "x": x_si, "F": F_si, "virgin": vc, "stribeck": st_si, "sigma": sigma_si, "slip_law": slip_law, "model": model,
                "position_unit": position_unit, "force_unit": force_unit, "time_unit": time_unit, "to_si": dict(to_si),
                "force_offset": float(info.get("force_offset", 0.0)) * kf}
    res = IdentificationResult("presliding", params, units, info, data=data_out, model_object=model,
                               covariance=(list(params), cov_kw * np.outer(scale, scale)))
    emit(res, findings)
    return res


def _determined(fit: BlockFit, mask: NDArray[np.bool_], data: _HysteresisData, resolution: float, limit: float = 0.5) -> bool:
    """Every stiffness and break force of a force fit known to better than ``limit`` (relative
    standard error): a block the data barely show does not justify a larger count."""
    cov_q, cov_rev, _, _ = _hysteresis_covariance(fit, mask, data.x, resolution, data.sigma_reversal)
    cov = _kw_covariance(cov_q + cov_rev, fit.k, fit.w, log_w=False)
    rel = np.sqrt(np.clip(np.diag(cov), 0, np.inf)) / np.concatenate((fit.k, fit.w))
    return bool(np.all(np.isfinite(rel)) and np.all(rel <= limit))


def _added_knot_starts(data: _HysteresisData, fit: BlockFit, mask: NDArray[np.bool_], lo: float, hi: float, keep: int = 1) -> list[BlockFit]:
    """Starts for one block more than ``fit``: its knots with one added in every gap (and at
    both ends), ranked by the cost of the linear solve at those knots (one simulation each);
    the ``keep`` best (each costs a full force fit)."""
    edges = np.concatenate(([lo * 1.5], fit.d, [hi / 1.2]))
    weight = fit.extra["weight"]
    lin = _LinearBlocks(data.F[mask], weight, offset=True)
    scored = []
    for a, b in zip(edges[:-1], edges[1:]):
        if not b > a:
            continue
        d0 = np.sort(np.concatenate((fit.d, [np.sqrt(a * b)])))
        k0, _, r = lin.solve(_play(data.t, data.x, d0)[mask])
        scored.append((float(r @ r), BlockFit(np.maximum(k0, 1e-12 * max(float(k0.max()), 1e-300)), d0, float(r @ r), True)))
    scored.sort(key=lambda s: s[0])
    return [f for _, f in scored[:keep]]


def _force_stage(data: _HysteresisData, vc: VirginCurve, fits: dict[int, list[BlockFit]], order: list[int], lo: float, hi: float, compare: bool,
                 progress: bool) -> tuple[int, BlockFit, BlockFit, NDArray[np.bool_], bool, dict[int, float]]:
    """Force fits: the first count in ``order`` whose blocks the record supports; with
    ``compare`` (the count is not given) its neighbours too, and the count whose force fit has
    the best BIC on the same samples and weights (the force record holds more than the virgin
    curve: the virgin loading, every branch beyond the Masing range)."""
    runs: dict[int, tuple[BlockFit, BlockFit, NDArray[np.bool_], bool]] = {}

    def run(nb: int) -> bool:
        if nb not in fits:
            return False
        vfit = next((f for f in fits[nb] if f.admissible), fits[nb][0])
        others = [f for f in fits[nb] if f is not vfit and f.admissible][:1]
        if nb - 1 in runs:
            # the force fit of one block fewer with a knot added: the virgin curve may have
            # merged two blocks that the whole record tells apart
            others += _added_knot_starts(data, runs[nb - 1][1], runs[nb - 1][2], lo, hi)
        fit, mask, virgin = _fit_hysteresis(data, vfit, others, list(vc.turning_points), lo, hi, vc.resolution, progress)
        # The admissibility test compares the blocks with each other and cannot see all of them
        # collapse: break forces that explain nothing of the record's force swing are no fit.
        swing = 0.5 * float(np.ptp(data.F))
        if fit.admissible and not float(np.sum(fit.w)) >= 1e-3 * swing:
            fit.admissible = False
            fit.reason = f"the fit collapsed (total break force {float(np.sum(fit.w)):.3g} against a force swing of {swing:.3g}, SI)"
        runs[nb] = (vfit, fit, mask, virgin)
        return fit.admissible

    chosen = next((nb for nb in order if run(nb)), None)
    if chosen is None:
        last = runs[order[-1]][1] if order[-1] in runs else fits[order[-1]][0]
        hint = "" if compare else " (try fewer blocks)"
        raise IdentificationError(f"the data do not support {order[0]} blocks: {last.reason}{hint}")
    force_bic: dict[int, float] = {}
    if compare:
        _, ref, mask, _ = runs[chosen]
        weight = ref.extra["weight"]

        def score(nb: int) -> float:
            f = runs[nb][1]
            model = _play(data.t, data.x, f.d) @ f.k + f.offset
            r = (model[mask] - data.F[mask]) * weight
            return float(r @ r)

        n = int(mask.sum())
        n_eff = n / autocorrelation_inflation(ref.extra["residual"])

        def criterion(nb: int) -> float:
            return float(n_eff * np.log(max(score(nb), 1e-300) / n) + (2 * nb + 1) * np.log(n_eff))

        best = chosen
        force_bic[best] = criterion(best)
        # Each direction goes on past a worse, inadmissible or undetermined count (BIC need not
        # be unimodal: a count that merges two blocks can be worse than both its neighbours),
        # until ``SEARCH_BEYOND`` counts beyond the best so far.
        for step in (-1, 1):
            nb = chosen + step
            while nb in fits and abs(nb - best) <= SEARCH_BEYOND:
                if nb not in runs:
                    run(nb)
                fit_nb = runs[nb][1] if nb in runs else None
                if fit_nb is not None and fit_nb.admissible and (step < 0 or _determined(fit_nb, runs[nb][2], data, vc.resolution)):
                    force_bic[nb] = criterion(nb)
                    if force_bic[nb] < force_bic[best]:
                        best = nb
                nb += step
        chosen = best
    vfit, fit, mask, virgin = runs[chosen]
    return chosen, vfit, fit, mask, virgin, force_bic


def _virgin_stage(vc: VirginCurve, n_blocks: int | None, max_blocks: int, hi_force: float) -> tuple[dict[int, list[BlockFit]], list[int], dict[int, float]]:
    """Virgin fits for every candidate count (each starting also from the previous count's
    solution), and the counts to try in order: the given one, or all ranked by BIC."""
    top = int(n_blocks) if n_blocks is not None else max_blocks
    fits: dict[int, list[BlockFit]] = {}
    previous = None
    for nb in range(1, top + 1):
        if n_blocks is not None and nb < top - 1:
            continue  # a fixed count needs only its neighbour below (for the added-knot starts)
        fits[nb] = _fit_virgin(vc, nb, previous, hi_force=hi_force)
        previous = fits[nb][0]
    u, _, _, _, _ = _virgin_points(vc)
    # effective sample size from the residual of the richest fit (correlated along the branches)
    n_eff = u.size / autocorrelation_inflation(_virgin_residual(vc, fits[top][0]))
    if n_blocks is not None:
        return fits, [top], {top: _bic(fits[top][0], u.size, n_eff)}
    order, bic = _rank_block_counts({nb: fits[nb][0] for nb in range(1, top + 1)}, vc, u.size, n_eff)
    return fits, order, bic


def _kw_covariance(cov: NDArray[np.float64], k: NDArray[np.float64], w: NDArray[np.float64], *, log_w: bool) -> NDArray[np.float64]:
    """Covariance of ``(k, w)`` from that of ``(log k, log d[, offset])`` (``w = k d``) or of
    ``(log k, log w[, offset])``."""
    nb = k.size
    J = np.zeros((2 * nb, cov.shape[0]))
    J[:nb, :nb] = np.diag(k)
    if not log_w:
        J[nb:, :nb] = np.diag(w)
    J[nb:, nb:2 * nb] = np.diag(w)
    return transform_covariance(cov, J)


def _virgin_residual(vc: VirginCurve, fit: BlockFit) -> NDArray[np.float64]:
    """Weighted residual of a virgin fit at the points, in the order of the record (so the
    correlation along each branch shows)."""
    u, g, weight, _, _ = _virgin_points(vc)
    r = (virgin_model(u, fit.k, fit.d) - g) * weight
    order = np.argsort(vc.sample[vc.u > 0], kind="stable")
    return r[order]
