"""The identification loop: baseline, residual analysis, one effect at a time, held-out test.

Each round every applicable catalogue effect is fitted on the estimation rows (its nonlinear
parameters chosen by blocked cross-validation *inside* the estimation rows), then ranked by
that cross-validated gain.  The best-ranked effect that passes all three tests is added:

1. held-out error drops by at least ``min_gain`` (relative);
2. the drop is larger than noise would give: paired test over contiguous chunks of the held-out
   rows, ``t = mean(d) / se(d) > t_threshold`` with ``d`` the per-chunk decrease of the squared
   error;
3. the Bayesian information criterion on the estimation rows decreases (grid-selected
   nonlinear parameters count as parameters).

The loop stops when no effect passes.  Residual structure left at the end is reported as
unexplained, with the variable it correlates with.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from .._progress import Progress
from .._validate import finite, non_negative
from ..errors import IdentificationError, InvalidInputError
from .data import AxisData
from .effects import CATALOGUE, Effect
from .idim import REFERENCE_MODEL, Array, BASE_TERMS, LinearModel, Preprocessing, Signals, relative_error
from .residuals import Finding, analyse
from .results import LoopResult, Step


@dataclass(frozen=True)
class LoopConfig:
    """Settings of :func:`run_loop`.

    Parameters
    ----------
    preprocessing : Preprocessing
        Filter and decimation (the EMPS recipe by default).
    baseline : sequence of str
        Baseline terms among ``inertia, viscous, coulomb, offset`` (default: the EMPS reference
        model, all four).
    effects : sequence of str, optional
        Catalogue effects to try (default: all of :data:`gmsfric.loop.CATALOGUE`).
    holdout_fraction : float
        Without a validation run: fraction of the estimation run held out, as interleaved
        contiguous blocks.
    n_blocks : int
        Number of blocks the run is cut into for that split.
    inner_folds : int
        Folds of the blocked cross-validation on the estimation rows.
    t_threshold : float
        Paired-chunk t statistic the held-out improvement must exceed.
    min_gain : float
        Smallest relative decrease of the held-out error that counts (0.01 = 1 %).
    max_effects : int
        Upper bound on the number of added effects.
    sampling_hold : bool
        Before the catalogue, try aligning the force half a sample later (a command held over
        each sample acts, on average, half a sample after its time stamp).  Kept only when the
        held-out data confirm it; reported under ``alignment``, not as an effect.
    seed : int
        Seed of the residual tests' surrogates.
    progress : bool
        Show progress on stderr.
    """

    preprocessing: Preprocessing = Preprocessing()
    baseline: Sequence[str] = REFERENCE_MODEL
    effects: Sequence[str] | None = None
    holdout_fraction: float = 0.3
    n_blocks: int = 10
    inner_folds: int = 5
    t_threshold: float = 3.0
    min_gain: float = 0.01
    max_effects: int = 6
    sampling_hold: bool = True
    seed: int = 0
    progress: bool = True

    def __post_init__(self) -> None:
        f = finite("holdout_fraction", self.holdout_fraction)
        if not 0.0 < f < 1.0:
            raise InvalidInputError(f"`holdout_fraction` must be between 0 and 1 (exclusive), got {f}")
        for name, low in (("n_blocks", 1), ("inner_folds", 2), ("max_effects", 0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
                raise InvalidInputError(f"`{name}` must be an integer >= {low}, got {v!r}")
        finite("t_threshold", self.t_threshold)
        non_negative("min_gain", self.min_gain)


@dataclass
class Split:
    """Estimation and held-out rows: ``(signals, row mask)`` each."""

    est: Signals
    est_rows: Array
    val: Signals
    val_rows: Array
    holdout: str

    def errors(self, m: LinearModel) -> tuple[float, float]:
        e = relative_error(self.est.y[self.est_rows], m.predict(self.est)[self.est_rows])
        v = relative_error(self.val.y[self.val_rows], m.predict(self.val)[self.val_rows])
        return e, v


def make_split(est: AxisData, val: AxisData | None, cfg: LoopConfig) -> Split:
    """Preprocess the runs and choose the held-out rows (a validation run, or interleaved
    blocks of the estimation run)."""
    s = Signals(est, cfg.preprocessing)
    if val is not None:
        v = Signals(val, cfg.preprocessing, q_range=s.q_range)
        return Split(s, np.ones(s.n_rows, bool), v, np.ones(v.n_rows, bool), val.source)
    n = s.n_rows
    nb = max(3, cfg.n_blocks)
    block = np.minimum((np.arange(n) * nb) // n, nb - 1)
    n_val = max(1, int(round(cfg.holdout_fraction * nb)))
    val_blocks = np.round(np.linspace(1, nb - 2, n_val)).astype(int) if n_val < nb - 1 else np.arange(1, nb, 2)
    val_mask = np.isin(block, val_blocks)
    return Split(s, ~val_mask, s, val_mask, f"{est.source} (held-out blocks {', '.join(str(b + 1) for b in val_blocks)} of {nb})")


def _cv_sse(X: Array, y: Array, folds: int) -> float:
    """Blocked K-fold cross-validated SSE, from per-fold normal equations (columns scaled)."""
    n = y.size
    scale = np.sqrt((X**2).sum(axis=0))
    scale[scale == 0] = 1.0
    Xs = X / scale
    idx = np.minimum((np.arange(n) * folds) // n, folds - 1)
    G = [(Xs[idx == k].T @ Xs[idx == k], Xs[idx == k].T @ y[idx == k]) for k in range(folds)]
    GT = sum(g for g, _ in G)
    bT = sum(b for _, b in G)
    ridge = 1e-10 * np.trace(GT) / GT.shape[0]
    sse = 0.0
    for k in range(folds):
        A = GT - G[k][0] + ridge * np.eye(GT.shape[0])
        theta = np.linalg.lstsq(A, bT - G[k][1], rcond=None)[0] if not np.all(np.isfinite(A)) else _solve(A, bT - G[k][1])
        r = y[idx == k] - Xs[idx == k] @ theta
        sse += float(r @ r)
    return sse


def _solve(A: Array, b: Array) -> Array:
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def _chunk_t(r0: Array, r1: Array, chunk: int) -> float:
    """Paired t statistic of ``log(SSE_before / SSE_after)`` over contiguous chunks.

    The log ratio is scale-free, so a few chunks with large forces (reversals, pulses) do not
    swamp the others; under "no improvement" its mean is zero (or below, for overfitted
    effects)."""
    m = max(2, r0.size // chunk)
    c = r0.size // m
    a = (r0[: m * c] ** 2).reshape(m, c).sum(axis=1)
    b = (r1[: m * c] ** 2).reshape(m, c).sum(axis=1)
    d = np.log((a + 1e-300) / (b + 1e-300))
    sd = d.std(ddof=1)
    if sd == 0:
        return float(np.sign(d.mean()) * np.inf) if d.mean() else 0.0
    return float(d.mean() / (sd / np.sqrt(m)))


def _evaluate(split: Split, m: LinearModel, cfg: LoopConfig) -> tuple[float, float]:
    """Blocked CV SSE on estimation rows, and the number of rows."""
    X = m.X(split.est)[split.est_rows]
    return _cv_sse(X, split.est.y[split.est_rows], cfg.inner_folds), float(X.shape[0])


def run_loop(est: AxisData, val: AxisData | None = None, config: LoopConfig | None = None) -> LoopResult:
    """Fit the baseline, then add catalogue effects one at a time while held-out data agree.

    Parameters
    ----------
    est : AxisData
        Estimation run.
    val : AxisData, optional
        Validation run (cross-test).  Without it, interleaved blocks of ``est`` are held out.
    config : LoopConfig, optional

    Returns
    -------
    LoopResult
        Baseline, steps, final model, errors (``100 ||f - f_hat|| / ||f||`` on the decimated
        force rows), unexplained residual structure and the residual tests.
    """
    cfg = config or LoopConfig()
    names = list(cfg.effects) if cfg.effects is not None else list(CATALOGUE)
    unknown = [n for n in names if n not in CATALOGUE]
    if unknown:
        raise IdentificationError(f"unknown effect(s) {unknown}; catalogue: {', '.join(CATALOGUE)}")
    for b in cfg.baseline:
        if b not in BASE_TERMS:
            raise IdentificationError(f"unknown baseline term {b!r}; use {', '.join(BASE_TERMS)}")
    split = make_split(est, val, cfg)
    S, er = split.est, split.est_rows
    n_est = int(er.sum())
    chunk = max(10, int(round(0.25 / (S.dt * S.dec))))  # ~0.25 s of rows per chunk
    chunk = min(chunk, max(10, int(split.val_rows.sum()) // 24))

    base = LinearModel([BASE_TERMS[b] for b in cfg.baseline]).fit(S, er)
    base_err = split.errors(base)
    current = base
    cur_err = base_err
    alignment: dict[str, Any] = {"sampling_hold_s": 0.5 * S.dt, "applied": False, "tests": []} if cfg.sampling_hold else {}

    def try_hold(cur: LinearModel, cur_e: tuple[float, float], rnd: int) -> tuple[LinearModel, tuple[float, float]]:
        # A force recorded as a command held over [t_k, t_k+1) acts, on average, half a sample
        # after its time stamp: a property of the sampling, not of the axis (nothing fitted).
        # Tested again after every added effect: a large effect can hide it at first.
        if not cfg.sampling_hold or alignment["applied"] or cur.delay:
            return cur, cur_e
        held = cur.copy()
        held.theta = None
        held.delay = 0.5 * S.dt
        held.fit(S, er)
        e_h = split.errors(held)
        r0 = (split.val.y - cur.predict(split.val))[split.val_rows]
        r1 = (split.val.y - held.predict(split.val))[split.val_rows]
        t_h = _chunk_t(r0, r1, chunk)
        ok_h = t_h >= cfg.t_threshold and 1.0 - e_h[1] / cur_e[1] >= cfg.min_gain
        alignment["tests"].append({"after_round": rnd, "t_heldout": round(t_h, 2), "estimation_error_pct": round(e_h[0], 4), "validation_error_pct": round(e_h[1], 4), "applied": bool(ok_h)})
        if ok_h:
            alignment["applied"] = True
            held.extras["sampling_hold_s"] = 0.5 * S.dt
            return held, e_h
        return cur, cur_e

    current, cur_err = try_hold(current, cur_err, 0)
    steps: list[Step] = []
    findings: dict[str, list[Finding]] = {}
    rnd = 0
    with Progress("gmsfric loop", enabled=cfg.progress) as prog:
        while len(current.effects) < cfg.max_effects:
            rnd += 1
            y_hat = current.predict(S)
            r = S.y - y_hat
            fnd = {f.variable: f for f in _analyse_rows(S, er, r, y_hat, cfg.seed)}
            r_est = np.where(er, r, np.nan)
            if rnd == 1:
                findings["baseline_estimation"] = list(fnd.values())
            cv_cur, _ = _evaluate(split, current, cfg)
            sse_cur = float(((S.y - current.predict(S))[er] ** 2).sum())
            cands: list[tuple[float, Effect, LinearModel]] = []
            for eff in (CATALOGUE[n] for n in names):
                if not eff.applicable(current):
                    continue
                best: tuple[float, LinearModel] | None = None
                why: str | None = None
                for m in eff.variants(current, S, r_est):
                    try:
                        if eff.physical is not None:
                            why = eff.check(m.fit(S, er))
                            if why is not None:
                                continue
                        cv, _ = _evaluate(split, m, cfg)
                    except (IdentificationError, np.linalg.LinAlgError, ValueError):
                        continue
                    if best is None or cv < best[0]:
                        best = (cv, m)
                    prog.update(note=f"round {rnd}: {eff.name}")
                if best is not None:
                    cands.append((1.0 - best[0] / cv_cur, eff, best[1]))
                elif why is not None:
                    f = fnd.get(eff.evidence)
                    ev0: dict[str, Any] = {"residual_test": f.as_dict()} if f is not None else {}
                    steps.append(Step(rnd, eff.name, False, f"no physically valid fit ({why})", ev0, float("nan"), float("nan"), {}))
            cands.sort(key=lambda c: -c[0])
            accepted = None
            for gain_cv, eff, m in cands:
                m.fit(S, er)
                e_est, e_val = split.errors(m)
                r0 = (split.val.y - current.predict(split.val))[split.val_rows]
                r1 = (split.val.y - m.predict(split.val))[split.val_rows]
                t = _chunk_t(r0, r1, chunk)
                sse_new = float(((S.y - m.predict(S))[er] ** 2).sum())
                dbic = n_est * np.log(sse_new / sse_cur) + (m.n_params - current.n_params) * np.log(n_est)
                val_gain = 1.0 - e_val / cur_err[1]
                ev: dict[str, Any] = {}
                f = fnd.get(eff.evidence)
                if f is not None:
                    ev["residual_test"] = f.as_dict()
                ev.update(cv_gain=round(gain_cv, 5), validation_gain=round(val_gain, 5), t_heldout=round(t, 2), delta_bic=round(float(dbic), 1))
                reasons = []
                if gain_cv <= 0:
                    reasons.append("no cross-validated gain on estimation data")
                if val_gain < cfg.min_gain:
                    reasons.append(f"held-out error gain {100 * val_gain:.2f} % < {100 * cfg.min_gain:.2f} %")
                if t < cfg.t_threshold:
                    reasons.append(f"held-out gain within noise (t = {t:.2f} < {cfg.t_threshold})")
                if dbic >= 0:
                    reasons.append(f"BIC does not decrease ({dbic:+.1f})")
                ok = not reasons and accepted is None
                if ok:
                    reason = f"held-out error {cur_err[1]:.3f} -> {e_val:.3f} % (t = {t:.1f}), BIC {dbic:+.1f}"
                elif not reasons:
                    reason = "passes, but a better-ranked effect was added this round"
                else:
                    reason = "; ".join(reasons)
                steps.append(Step(rnd, eff.name, ok, reason, ev, e_est, e_val, m.params(), m))
                if ok:
                    accepted = (m, (e_est, e_val))
            if accepted is None:
                break
            current, cur_err = accepted
            current, cur_err = try_hold(current, cur_err, rnd)
    y_hat = current.predict(S)
    r = S.y - y_hat
    final_f = _analyse_rows(S, er, r, y_hat, cfg.seed)
    findings["final_estimation"] = final_f
    unexplained = []
    for f in final_f:
        if f.significant:
            tried = [e for e in f.suggests if e in names]
            unexplained.append({"variable": f.variable, "run": "estimation", "z": round(f.z, 1), "statistic": round(f.statistic, 5),
                                "candidates_tried": tried, "note": "residual still depends on " + f.variable + "; no catalogue effect reduced the held-out error enough",
                                **{k: v for k, v in f.detail.items()}})
    if split.val is not split.est:
        yv = current.predict(split.val)
        fv = analyse(split.val, split.val.y - yv, yv, seed=cfg.seed)
        findings["final_validation"] = fv
        for f in fv:
            if f.significant:
                unexplained.append({"variable": f.variable, "run": "validation", "z": round(f.z, 1), "statistic": round(f.statistic, 5),
                                    "candidates_tried": [e for e in f.suggests if e in names], "note": "structure in the held-out run's residual", **{k: v for k, v in f.detail.items()}})
    return LoopResult(split, base, base_err, steps, current, cur_err, unexplained, findings, alignment=alignment)


def _analyse_rows(S: Signals, rows: Array, r: Array, y_hat: Array, seed: int) -> list[Finding]:
    """Residual tests on a subset of rows (contiguous blocks are concatenated)."""
    if rows.all():
        return analyse(S, r, y_hat, seed=seed)
    sub = _SubSignals(S, rows)
    return analyse(sub, r[rows], y_hat[rows], seed=seed)  # type: ignore[arg-type]


class _SubSignals:
    """A view of some rows of a :class:`Signals` for the residual tests."""

    def __init__(self, s: Signals, rows: Array) -> None:
        self.dt, self.dec, self.fs, self.v_scale = s.dt, s.dec, s.fs, s.v_scale
        self.y = s.y[rows]
        self.rows = {k: v[rows] for k, v in s.rows.items()}
