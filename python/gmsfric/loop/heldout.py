"""The estimation and held-out rows (:class:`Split`), and the comparison of two fitted models on
the held-out rows: the paired chunk test the selection decides by.

The held-out rows are cut into contiguous chunks of about a second (:func:`chunk_rows`); per chunk
the normalised decrease of the squared error ``d = (SSE_before - SSE_after) / (SSE_before +
SSE_after)`` is taken, and its mean is tested against zero with a Newey-West standard error
(:func:`paired_chunk_test`), on the chunks where the two models disagree
(:func:`informative_chunks`).  :func:`heldout` compares on the moving held-out rows (within the
estimation travel for models with a position basis, :func:`within_travel`), :func:`heldout_clear`
on the rows clear of reversals and stops (:func:`clear_rows`).  The selection's rules (levels,
minimum gains, which comparisons an effect must pass) are in :mod:`gmsfric.loop.select`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy import stats

from ..errors import IdentificationError
from .effects import CATALOGUE, dip_resolution, has_position_basis, settled_rows
from .idim import Array, LinearModel, Signals, relative_error

#: A held-out chunk where two models' predictions differ by less than this fraction of the mean
#: chunk's difference carries no evidence between them (:func:`informative_chunks`).  On a
#: trapezoid run a delay changes the force in the acceleration phases only: its cruise chunks
#: differ by under 1 % of the mean, its acceleration chunks by 40-800 %.
INFORMATIVE_FRACTION = 0.05

#: An effect that acts in some places only (:attr:`Effect.acting`) is also tested on the held-out
#: chunks where it acts at least this fraction of its mean chunk's.  A warm-up planted on
#: the real EMPS runs (6 N dying out over 10 s of 25 s) gains 15 % on held-out data, d = 0.14 to
#: 0.66 in the seven chunks where it acts and -0.18 to +0.22 in the twelve after it, where the
#: refitted baseline differs from the null's by the drift's mean: t = 1.5 over all nineteen.
ACTING_FRACTION = 1.0

#: The paired chunk test uses at least this many chunks.
MIN_TESTED_CHUNKS = 6


@dataclass
class Split:
    """Estimation and held-out rows: ``(signals, row mask)`` each, the moving rows of both that
    fits (``est_fit``) and tests (``val_test``) use, and the moving and creeping rows of both
    (``est_creep``, ``val_creep``: not stuck, faster than the creep speed) that the tests of a
    creeping effect use (:meth:`creeping`)."""

    est: Signals
    est_rows: Array
    val: Signals
    val_rows: Array
    holdout: str
    est_fit: Array = field(default=None)  # type: ignore[assignment]
    val_test: Array = field(default=None)  # type: ignore[assignment]
    est_creep: Array = field(default=None)  # type: ignore[assignment]
    val_creep: Array = field(default=None)  # type: ignore[assignment]
    #: How the position filter's cut-off was chosen (the JSON's ``preprocessing``).
    preprocessing: dict[str, Any] = field(default_factory=dict)
    #: Which rows fits and tests use, for reports.
    label: str = "moving"

    def __post_init__(self) -> None:
        if self.est_fit is None:
            self.est_fit = self.est_rows & self.est.moving
        if self.val_test is None:
            self.val_test = self.val_rows & self.val.moving
        if self.est_creep is None:
            self.est_creep = self.est_fit
        if self.val_creep is None:
            self.val_creep = self.val_test

    def creeping(self) -> "Split":
        """The same runs with the moving and creeping rows as the rows fits and tests use."""
        return replace(self, est_fit=self.est_creep, val_test=self.val_creep, label="moving and creeping")

    def errors(self, m: LinearModel) -> tuple[float, float]:
        """Estimation and held-out errors (%) on all rows (standstill included)."""
        e = relative_error(self.est.y[self.est_rows], m.predict(self.est)[self.est_rows])
        v = relative_error(self.val.y[self.val_rows], m.predict(self.val)[self.val_rows])
        return e, v

    def errors_moving(self, m: LinearModel) -> tuple[float, float]:
        """Estimation and held-out errors (%) on the moving rows (the ones the loop fits and tests)."""
        e = relative_error(self.est.y[self.est_fit], m.predict(self.est)[self.est_fit])
        v = relative_error(self.val.y[self.val_test], m.predict(self.val)[self.val_test])
        return e, v


@dataclass
class HeldOut:
    """A paired held-out comparison of two models."""

    t: float
    p: float
    gain: float
    chunks: int
    error_before: float
    error_after: float
    #: Whether only the rows within the estimation travel were compared (:func:`within_travel`).
    within_travel: bool = False
    #: The gain on every tested row, when ``gain`` is that within the estimation travel.
    gain_all_rows: float | None = None

    @property
    def ranking_gain(self) -> float:
        """The gain candidates are ranked by: on the same held-out rows for all of them."""
        return self.gain if self.gain_all_rows is None else self.gain_all_rows


def paired_chunk_test(r0: Array, r1: Array, chunk: int, acting: Array | None = None) -> tuple[float, float, int]:
    """One-sided test that ``r1`` is smaller than ``r0``: per contiguous chunk the normalised
    decrease of the squared error ``d = (SSE0 - SSE1) / (SSE0 + SSE1)``, its mean over a
    Newey-West standard error (the chunks' own autocorrelation counted), p-value from Student's
    t with ``m - 1`` degrees of freedom.

    ``d`` is scale-free and bounded (-1 to 1): every chunk weighs the same, a few chunks with
    large forces (reversals, pulses) do not swamp the others, and a chunk where both errors are
    small noise cannot produce an outlier.  For an effect fitted on other data and useless here
    its mean is zero or below.

    Only the chunks where the two models disagree are tested (:func:`informative_chunks`): where
    they predict the same force, ``d`` is noise about zero and would only dilute an effect that
    acts in a few places (a delay while the force changes, a contact at reversals).  The choice
    depends on ``r0 - r1``, the difference of the two predictions, not on the measured force, so
    a useless effect still has a mean ``d`` of zero or below.

    With ``acting`` (where an effect that acts in some places only acts, :attr:`Effect.acting`)
    the test is also made on the chunks where it acts at least :data:`ACTING_FRACTION` of its
    mean chunk's, and the smaller of the two p-values, doubled (Bonferroni), is returned with its
    ``t`` and ``m``: a warm-up shows where it acts, a contact after each reversal, while a drift
    spread over the run, or the refitted baseline, can hold the evidence elsewhere.
    Returns ``(t, p, m)`` with ``m`` the chunks tested."""
    m = max(2, r0.size // chunk)
    c = r0.size // m
    a = (r0[: m * c] ** 2).reshape(m, c).sum(axis=1)
    b = (r1[: m * c] ** 2).reshape(m, c).sum(axis=1)
    d = (a - b) / np.maximum(a + b, 1e-300)
    plain = _mean_test(d[informative_chunks(((r0 - r1)[: m * c] ** 2).reshape(m, c).sum(axis=1))])
    if acting is None:
        return plain
    where = _mean_test(d[informative_chunks((acting[: m * c] ** 2).reshape(m, c).sum(axis=1), ACTING_FRACTION)])
    t, p, k = min(plain, where, key=lambda r: r[1])
    return t, min(1.0, 2.0 * p), k


def _mean_test(d: Array) -> tuple[float, float, int]:
    """One-sided Student test that the mean of the chunks' ``d`` is above zero, with a Newey-West
    standard error: ``(t, p, m)``."""
    m = d.size
    mean = float(d.mean())
    dc = d - mean
    g0 = float(dc @ dc) / m
    lags = int(np.floor(m ** (1.0 / 3.0)))
    lrv = g0 + 2.0 * sum((1.0 - k / (lags + 1.0)) * float(dc[k:] @ dc[:-k]) / m for k in range(1, min(lags, m - 1) + 1))
    var = max(lrv, g0) / (m - 1)  # negative autocorrelation would shrink the error: never below the i.i.d. one
    if var <= 0:
        t = float(np.sign(mean) * np.inf) if mean else 0.0
    else:
        t = mean / float(np.sqrt(var))
    p = float(stats.t.sf(t, m - 1)) if np.isfinite(t) else (0.0 if t > 0 else 1.0)
    return float(t), p, m


def informative_chunks(disagreement: Array, fraction: float = INFORMATIVE_FRACTION) -> Array:
    """The chunks (mask) whose summed squared difference of the two models' predictions is at
    least ``fraction`` of the mean chunk's; at least :data:`MIN_TESTED_CHUNKS`
    (those that disagree most) when fewer do, all of them when the models agree everywhere."""
    m = disagreement.size
    mean = float(disagreement.mean())
    if m <= MIN_TESTED_CHUNKS or not mean > 0:
        return np.ones(m, dtype=bool)
    keep = disagreement >= fraction * mean
    if keep.sum() < MIN_TESTED_CHUNKS:
        keep = np.zeros(m, dtype=bool)
        keep[np.argsort(disagreement)[-MIN_TESTED_CHUNKS:]] = True
    return keep


def heldout(split: Split, before: LinearModel, after: LinearModel, chunk: int, rows: Array | None = None,
            effect: str | None = None) -> HeldOut:
    """Compare two fitted models on the moving held-out rows (or on ``rows`` of them); ``effect``:
    the effect ``after`` adds (its chunks tested where it acts when it acts over time).

    Models with a position basis are compared on the rows within the estimation travel
    (:func:`within_travel`) when the held-out run goes beyond it.  Candidates are ranked by
    their gain on every row (:attr:`HeldOut.ranking_gain`), the same rows for all of them."""
    rows = split.val_test if rows is None else rows
    y = split.val.y
    p0, p1 = before.predict(split.val), after.predict(split.val)
    where = CATALOGUE[effect].acting if effect is not None else None
    acting = where(after, split.val) if where is not None else None

    def errors(r: Array) -> tuple[float, float, float]:
        e0, e1 = relative_error(y[r], p0[r]), relative_error(y[r], p1[r])
        return e0, e1, 1.0 - e1 / e0 if e0 > 0 else 0.0

    def on(r: Array) -> HeldOut:
        t, p, m = paired_chunk_test(y[r] - p0[r], y[r] - p1[r], chunk, None if acting is None else acting[r])
        e0, e1, gain = errors(r)
        return HeldOut(t, p, gain, m, e0, e1)

    inside = within_travel(split, rows, chunk) if has_position_basis(before, after) else rows
    if inside.sum() == rows.sum():
        return on(rows)
    return replace(on(inside), within_travel=True, gain_all_rows=errors(rows)[2])


def within_travel(split: Split, rows: Array, chunk: int) -> Array:
    """``rows`` of the held-out run that lie within the travel of the moving estimation rows, when
    at least a ``chunk`` of them lie beyond it and :data:`MIN_TESTED_CHUNKS` chunks within it
    (else ``rows``).

    A position basis is known only where the axis has been: beyond the estimation travel it
    extrapolates (a polynomial grows without bound), and a held-out run that goes further would
    test that guess instead of whether the force depends on the position.  Models with a
    position basis are compared within the travel, as cross-validation scores them
    (:func:`_cv_sse`); a few rows beyond it cannot move the test."""
    q = split.est.rows["q"][split.est_fit]
    qv = split.val.rows["q"]
    inside = rows & (qv >= q.min()) & (qv <= q.max())
    return inside if rows.sum() - inside.sum() >= chunk and inside.sum() >= MIN_TESTED_CHUNKS * chunk else rows


@dataclass(frozen=True)
class ClearRows:
    """Moving rows clear of reversals and stops (faster than the blur of the filter, and settled
    after it in time): ``est`` of the estimation run (fits), ``val`` of the held-out run (tests)."""

    est: Array
    val: Array


def clear_rows(split: Split) -> ClearRows:
    """The moving rows of both runs clear of reversals and stops (speed from the estimation run)."""
    def clear(sig: Signals, moving: Array) -> Array:
        return settled_rows(sig) & (np.abs(sig.rows["qd"]) >= dip_resolution(split.est)) & moving.astype(bool)
    return ClearRows(clear(split.est, split.est_fit), clear(split.val, split.val_test))


def heldout_clear(split: Split, before: LinearModel, after: LinearModel, chunk: int, clear: ClearRows, refit: bool) -> HeldOut | None:
    """Compare two fitted models on the held-out rows clear of reversals and stops (``None`` when
    fewer than two ``chunk`` of them, the chunk of the test on all moving rows).  With ``refit``
    both are first fitted again on the estimation rows clear of them (their nonlinear parameters
    kept): what an effect gains there must not be the baseline parameters it frees from what the
    rows near reversals and stops pulled them to.  The test cuts the rows clear of reversals by
    the rule of the test on all rows (:func:`chunk_rows`) applied to their number: cut like all
    rows, a run that reverses often kept 6 to 10 chunks there, and a delay gaining 28 % on them
    reached t = 3.0 but only p = 0.015 on 5 degrees of freedom."""
    if clear.val.sum() < 2 * chunk:
        return None
    if refit:
        if clear.est.sum() < max(2 * chunk, 4 * after.n_params):
            return None
        try:
            before, after = before.copy().fit(split.est, clear.est), after.copy().fit(split.est, clear.est)
        except (IdentificationError, np.linalg.LinAlgError):
            return None
    return heldout(split, before, after, chunk_rows(split, int(clear.val.sum())), clear.val)


def chunk_rows(split: Split, n: int) -> int:
    """Rows per chunk of the paired test over ``n`` held-out rows: about a second, long against
    the residual's correlation time (the chunks' means are then nearly independent and the
    decrease of a chunk is not the ratio of two noise samples), and 20 to 60 of them for the t
    statistic; at least 10 rows."""
    S = split.est
    return max(int(np.clip(round(1.0 / (S.dt * S.dec)), n // 60, n // 20)), 10)
