"""The identification loop: baseline, timing alignment, effects added while held-out data agree.

The loop runs in named stages (:func:`run_loop`):

1. **prepare** -- preprocess both runs, choose the held-out rows, and mark standstill: rows where
   the axis is at rest carry a holding force anywhere up to break-away (set-valued stiction),
   which no regression column describes.  They are left out of every fit and every decision;
   errors are reported on all rows (the recipe's figure) and on the moving rows.  Rows slower
   than the standstill speed where the measured position still moves are *creeping*: the sign of
   the filtered velocity is noise there, so they are left out too, except where pre-sliding,
   whose blocks follow the measured position, is chosen, fitted and tested (with the model it is
   tested against); once it is in the model they join every fit and test.
2. **baseline** -- IDIM-LS fit of the baseline on the moving estimation rows, then the timing
   alignment: the force shifted by a fraction of one sample, chosen by cross-validation and kept
   when held-out data confirm it.  A command held over each sample acts half a sample after its
   time stamp on average, and where in its sample a logger stamps it is unknown: timing within
   one sample is a property of the sampling, not of the axis, and is not counted as an effect.
3. **select** -- rounds of forward selection with backward elimination.  In a round every
   applicable catalogue effect is fitted (its grid parameters chosen by blocked cross-validation
   inside the estimation rows: the held-out rows never choose a variant; the grid parameters of
   the effects already accepted are chosen again alongside it, since each was chosen without it)
   and tested on the held-out rows against the current model:

   * a paired test over contiguous chunks of held-out rows of the normalised decrease
     ``d = (SSE_before - SSE_after) / (SSE_before + SSE_after)``,
     with a heteroscedasticity- and autocorrelation-consistent (Newey-West) standard error, gives
     a one-sided p-value (Student t);
   * the false-effect rate is held across the catalogue and all rounds: round ``r`` spends
     ``alpha / 2**r`` of the family-wise level, split equally (Bonferroni) over the ``K``
     effects it tests, so an effect enters only with ``p <= alpha / (2**r K)``; the sum over
     rounds stays below ``alpha``.  ``K`` counts the effects that pass the checks made on the
     estimation run alone (a physical fit, a cross-validated gain of at least
     ``min_estimation_gain``, a lower BIC, a plausible baseline; :func:`_screened`): the others
     are refused whatever the held-out run shows, and since the two runs' noise is independent,
     screening on the one does not bias the test on the other;
   * an effect that acts on the whole motion (a delay, a resonance) must pass the same test on the
     held-out rows clear of reversals and stops: what gains only there is the switch of friction
     seen through the velocity filter;
   * the held-out error must also drop by ``min_gain`` (relative), the BIC on the estimation
     rows must decrease, the effect's own parameters must be physical, and the baseline's
     physical parameters must stay plausible: mass and effective viscous coefficient physical,
     the effective Coulomb level (all friction terms projected on ``sign(qd)``, ``qd``) not below
     ``1 / max_parameter_ratio`` of the baseline's, unless the step makes an unphysical
     baseline's mass and viscous coefficient physical -- an effect may not buy its gain by
     explaining the friction away.

   Models with a position basis are tested on the held-out rows within the estimation travel
   when the held-out run goes beyond it (a basis is known only where the axis has been), and
   ranked by their gain on every row.  Among the effects that pass, the one with the largest
   held-out gain enters (effects compete on the same held-out rows).  Then every accepted effect's grid parameters and the alignment are
   chosen again given the others (joint refit), and every earlier effect is tested again on the
   held-out rows given all the others (backward elimination, kept only with ``p <= alpha`` and
   the minimum gain): an effect that another one explains better leaves the model.

   When no single effect passes, two confounded effects may enter together, their grid
   parameters chosen again together.  Any two candidates are tried whose joint fit lowers the
   estimation run's cross-validated error by ``min_estimation_gain`` (one may fit worse alone,
   absorbing the other's force the wrong way); each must pass the held-out test given the other (level of
   the next round, split over the pairs tried), so a real effect cannot carry a false one in
   (:func:`_pair_step`).  When no pair passes either, each accepted effect is tried replaced by
   each catalogue effect not in the model, tested as an entering effect is in its place and
   required to beat the current model (:func:`_exchange_step`): a stand-in that entered first
   cannot keep out the effect it stands in for.  The other form of an accepted phenomenon
   (:data:`~gmsfric.loop.effects.ALTERNATIVE_FORMS`: a drift in time or heating) adds no
   effect, so it is tested at the nominal ``alpha`` and must beat the current model on the
   held-out run only: the estimation run alone hardly tells the two forms apart.
4. **report** -- residual analysis of the final model; significant structure left is listed as
   unexplained, with the variable it depends on.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Sequence

import numpy as np
from scipy import optimize

from .._progress import Progress
from .._validate import count, finite
from ..errors import IdentificationError, InvalidInputError
from ..identify.diagnostics import emit
from .checks import check_result
from .data import GAP_STEPS, AxisData, on_the_same_turn
from .effects import CATALOGUE, DELAY_STEPS, Effect, alternative_forms, detection_limits, has_position_basis, switch_timing
from .heldout import ClearRows, HeldOut, Split, chunk_rows, clear_rows, heldout, heldout_clear, paired_chunk_test
from .idim import REFERENCE_MODEL, Array, BASE_TERMS, LinearModel, Preprocessing, Signals, Term, relative_error, term_rows
from .residuals import Finding, analyse
from .results import LoopResult, Step, parameter_unit

#: Fractions of one sample tried for the timing alignment.
ALIGNMENT_GRID = np.round(np.linspace(0.0, 1.0, 11), 3)

#: A contested variant (:attr:`Effect.contested`, e.g. a Stribeck hump that never falls, which a
#: drag resembles) stands only with a cross-validated error at most this fraction of the best
#: probe's.  On the campaign's drag rigs the best such hump came within 0.97-1.0 of the drag probe,
#: on rigs with a planted hump down to 0.3.
CONTESTED_MARGIN = 0.95

#: A rival (:attr:`Effect.rivals`) refuses an effect only with a cross-validated error at most
#: this fraction of the chosen variant's.  On the campaign's force-ripple rigs the tone in time
#: fitted at 0.06-0.5 of the resonance's error and on rigs with resonances at 1.06 or more; where
#: the data hold neither (the "resonance" gaining nothing) both fit alike, 0.96-1.0.
RIVAL_MARGIN = 0.9

#: Passes of the joint refit.  One pass chooses each effect given the others as they were, and
#: the timing alignment chosen after it can make a better choice possible (a force shifted by one
#: sample, then pre-sliding with two blocks instead of one: 28 % lower cross-validated error on
#: the second pass in one campaign case).  Passes stop when one lowers
#: the error by less than :data:`JOINT_REFIT_TOL` (relative).
JOINT_REFIT_PASSES = 4
JOINT_REFIT_TOL = 1e-3

#: Share of its held-out gain on all moving rows that a delay the rows clear of reversals confirm
#: only at the nominal level must keep there (and at least the minimum gain) to be added: a delay
#: of the whole force gains wherever the axis accelerates (real delays of the campaign kept
#: 0.36-1.8 of it there), a sticking contact's lag mostly next to reversals (clean static-contact
#: rigs: 0.19-0.21).
DELAY_CLEAR_SHARE = 1.0 / 3.0

#: Share of its held-out gain on all moving rows that a delay must keep beyond a freely timed
#: switch of friction for that comparison to need only the nominal level.  A late filtered switch
#: taken for a delay keeps little beyond it (false delays of the campaign: 2-15 %); a real delay
#: keeps about all (seed 103 ``single-101``: 91 % of 89 %, over the six chunks where the models
#: differ: t = 2.6).
DELAY_SWITCH_SHARE = 0.5

#: A delay's held-out gain held by one spectral line: the line's relative half-width, the share of
#: the gain (decrease of the residual's power) in it and the largest share of the motion's
#: (velocity's) power there (:func:`single_tone`).  On the campaign's force-ripple rigs (a tone in
#: time outside the catalogue) the delays named kept 0.79-0.95 of their gain within 5 % of the
#: ripple's frequency, where the motion had 0.2-1.2 % of its power, and gained nothing without
#: that line (t = -8.0 to 0.8); real delays kept 0.04-0.31, except one that makes its loop chatter
#: (an outside audit's rig: 0.81 at 38 Hz, motion 0.0 %, and t = 12.4 without the line).
TONE_HALF_WIDTH = 0.05
TONE_GAIN_SHARE = 0.6
TONE_MOTION_SHARE = 0.05
#: :func:`single_tone` where the held-out rows show no line (too few, or no gain at all).
NO_LINE = {"line_hz": 0.0, "share": 0.0, "motion": 1.0, "t_off": 0.0, "p_off": 1.0}

#: Terms whose force is friction (their sum is projected on ``Fc sign(qd) + Fv qd`` to follow the
#: effective Coulomb and viscous levels of a model).  ``asymmetric_friction`` is left out: its
#: force is even in the speed, it splits the friction between the two directions and leaves the
#: level they share as it is; projected on ``sign(qd)`` over a run that moves faster one way than
#: the other it would still look like a change of that level.
FRICTION_TERMS = frozenset({"coulomb", "viscous", "stribeck", "presliding_hysteresis",
                            "position_dependent_friction", "friction_drift", "heating"})


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
        contiguous blocks (between 0 and 1, exclusive).
    n_blocks : int
        Number of blocks the run is cut into for that split (>= 3).
    inner_folds : int
        Folds of the blocked cross-validation on the estimation rows (>= 2).
    alpha : float
        Family-wise level of the held-out tests over the whole catalogue and all rounds: the
        probability of adding at least one effect the data do not support, when the tests'
        assumptions hold (between 0 and 0.5).
    t_threshold : float
        Floor on the held-out t statistic, on top of the corrected level (>= 0).
    min_gain : float
        Smallest relative decrease of the held-out error that counts (0.01 = 1 %; in [0, 1)).
    min_estimation_gain : float
        Smallest relative decrease of the cross-validated error on the estimation rows (the
        root of its SSE, the measure of ``min_gain``) that counts, in [0, 1): an effect that a
        held-out run finds material but that explains little of the run it was fitted on gains
        there by what it happens to resemble in that run.
    max_parameter_ratio : float
        An effect may lower the baseline's effective Coulomb level by at most this factor (> 1),
        unless it makes an unphysical baseline's mass and viscous coefficient physical; the mass
        and viscous coefficient must stay physical.
    rest_fraction : float
        Rows slower than this fraction of the run's speed scale (99th percentile of ``|qd|``) are
        standstill, left out of fits and tests (in [0, 0.5)).
    creep_fraction : float
        Rows slower than ``rest_fraction`` but at least this fraction of the speed scale, where the
        measured position moves (not stuck), are creeping: left out like standstill, except by the
        effects whose evidence lies there (pre-sliding, :attr:`Effect.creeping`), which are chosen,
        fitted and tested on the moving and creeping rows (in [0, 0.5); at or above
        ``rest_fraction`` no row creeps).
    max_effects : int
        Upper bound on the number of added effects (>= 0).
    sampling_hold : bool
        Try the timing alignment (the force shifted by up to one sample, nothing else fitted);
        kept only when held-out data confirm it and reported under ``alignment``, not as an effect.
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
    alpha: float = 0.05
    t_threshold: float = 3.0
    min_gain: float = 0.05
    min_estimation_gain: float = 0.025
    max_parameter_ratio: float = 2.0
    rest_fraction: float = 0.01
    creep_fraction: float = 0.002
    max_effects: int = 6
    sampling_hold: bool = True
    seed: int = 0
    progress: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.preprocessing, Preprocessing):
            raise InvalidInputError(f"`preprocessing` must be a Preprocessing, got {type(self.preprocessing).__name__}")
        f = finite("holdout_fraction", self.holdout_fraction)
        if not 0.0 < f < 1.0:
            raise InvalidInputError(f"`holdout_fraction` must be between 0 and 1 (exclusive), got {f}")
        for name, low in (("n_blocks", 3), ("inner_folds", 2), ("max_effects", 0), ("seed", 0)):
            count(name, getattr(self, name), minimum=low)
        a = finite("alpha", self.alpha)
        if not 0.0 < a <= 0.5:
            raise InvalidInputError(f"`alpha` must be in (0, 0.5], got {a}")
        if finite("t_threshold", self.t_threshold) < 0:
            raise InvalidInputError(f"`t_threshold` must be >= 0, got {self.t_threshold}")
        for name in ("min_gain", "min_estimation_gain"):
            g = finite(name, getattr(self, name))
            if not 0.0 <= g < 1.0:
                raise InvalidInputError(f"`{name}` must be in [0, 1), got {g}")
        if finite("max_parameter_ratio", self.max_parameter_ratio) <= 1.0:
            raise InvalidInputError(f"`max_parameter_ratio` must be > 1, got {self.max_parameter_ratio}")
        rf = finite("rest_fraction", self.rest_fraction)
        if not 0.0 <= rf < 0.5:
            raise InvalidInputError(f"`rest_fraction` must be in [0, 0.5), got {rf}")
        cf = finite("creep_fraction", self.creep_fraction)
        if not 0.0 <= cf < 0.5:
            raise InvalidInputError(f"`creep_fraction` must be in [0, 0.5), got {cf}")
        if isinstance(self.baseline, str) or not all(isinstance(b, str) for b in self.baseline):
            raise InvalidInputError(f"`baseline` must be a sequence of term names, got {self.baseline!r}")
        unknown = [b for b in self.baseline if b not in BASE_TERMS]
        if unknown or not self.baseline:
            raise InvalidInputError(f"`baseline` has unknown term(s) {unknown}; use {', '.join(BASE_TERMS)}" if unknown else "`baseline` is empty")
        if self.effects is not None:
            if isinstance(self.effects, str) or not all(isinstance(e, str) for e in self.effects):
                raise InvalidInputError(f"`effects` must be a sequence of catalogue names, got {self.effects!r}")
            unknown = [e for e in self.effects if e not in CATALOGUE]
            if unknown:
                raise InvalidInputError(f"`effects` has unknown effect(s) {unknown}; catalogue: {', '.join(CATALOGUE)}")

    def gains_on_estimation(self, gain_cv: float) -> bool:
        """Whether a cross-validated SSE gain ``gain_cv`` on the estimation rows lowers their
        error by at least ``min_estimation_gain``."""
        return gain_cv > 0 and error_gain(gain_cv) >= self.min_estimation_gain

    def level(self, rnd: int, n_tests: int) -> float:
        """Per-test level of round ``rnd`` (1-based) with ``n_tests`` candidates."""
        return self.alpha * 0.5**rnd / max(n_tests, 1)


def sse_gain(sse: float, sse_reference: float) -> float:
    """The relative decrease ``1 - sse / sse_reference`` of a (cross-validated) SSE; NaN when the
    reference's is zero: a model that fits exactly leaves nothing to gain, and NaN is no gain to
    every check (:meth:`LoopConfig.gains_on_estimation`)."""
    return 1.0 - sse / sse_reference if sse_reference > 0 else float("nan")


def error_gain(gain: float) -> float:
    """The relative decrease of an error (the root of an SSE) that a relative decrease
    ``gain`` of the SSE makes."""
    return 1.0 - float(np.sqrt(max(1.0 - gain, 0.0)))


#: Moving estimation rows needed to choose the position filter's cut-off (as many as the loop
#: needs to run at all).
MIN_ROWS_TO_CHOOSE_CUTOFF = 50


def _held_out_blocks(n: int, cfg: LoopConfig) -> tuple[Array, str]:
    """Without a validation run: the mask of the interleaved held-out blocks and their names."""
    nb = max(3, cfg.n_blocks)
    block = np.minimum((np.arange(n) * nb) // n, nb - 1)
    n_val = max(1, int(round(cfg.holdout_fraction * nb)))
    val_blocks = np.round(np.linspace(1, nb - 2, n_val)).astype(int) if n_val < nb - 1 else np.arange(1, nb, 2)
    return np.isin(block, val_blocks), f"held-out blocks {', '.join(str(b + 1) for b in val_blocks)} of {nb}"


def _estimation_signals(est: AxisData, cfg: LoopConfig, held_out: bool) -> tuple[Signals, dict[str, Any]]:
    """The estimation run preprocessed, standstill marked with the configured rest fraction.

    Without a given cut-off, each of :meth:`Preprocessing.cutoffs` is tried and the one whose
    baseline has the smallest blocked cross-validated error on the moving estimation rows (those
    moving under every cut-off, held-out blocks left out) is kept: at 1 kHz and above only the
    recipe's 100 Hz is tried."""
    def prepared(pre: Preprocessing) -> Signals:
        s = Signals(est, pre)
        rest = cfg.rest_fraction * s.v_scale
        if rest != s.rest_speed:
            s.rest_speed = rest
            s.moving = s.moving_above(rest)
        return s

    pre = cfg.preprocessing
    first = prepared(pre)
    if pre.cutoff_hz is not None:
        limited = first.cutoff < pre.cutoff_hz  # at most 0.45 fs, below Nyquist
        return first, {"cutoff_hz": round(first.cutoff, 6), "chosen_by": f"given ({pre.cutoff_hz:g} Hz, limited to 0.45 x fs)" if limited else "given"}
    cutoffs = pre.cutoffs(first.fs)
    if len(cutoffs) == 1:
        return first, {"cutoff_hz": round(first.cutoff, 6), "chosen_by": "the recipe, min(100 Hz, fs / 10)"}
    sigs = {first.cutoff: first} | {c: prepared(replace(pre, cutoff_hz=c)) for c in cutoffs[1:]}
    rows = np.logical_and.reduce([s.moving for s in sigs.values()])
    if held_out:
        rows &= ~_held_out_blocks(first.n_rows, cfg)[0]
    if rows.sum() < MIN_ROWS_TO_CHOOSE_CUTOFF:
        return first, {"cutoff_hz": round(first.cutoff, 6), "chosen_by": f"the recipe (fewer than {MIN_ROWS_TO_CHOOSE_CUTOFF} moving rows to choose on)"}
    base = LinearModel([BASE_TERMS[b] for b in cfg.baseline])
    cv = {c: _cv_sse(base.X(s)[rows], s.y[rows], cfg.inner_folds) for c, s in sigs.items()}
    best = min(cv, key=lambda c: cv[c])
    return sigs[best], {"cutoff_hz": round(best, 6), "chosen_by": "cross-validated baseline error on the moving estimation rows",
                        "cv_sse": {f"{c:.4g}": float(f"{v:.6g}") for c, v in sorted(cv.items())}}


def make_split(est: AxisData, val: AxisData | None, cfg: LoopConfig) -> Split:
    """Preprocess the runs, choose the held-out rows (a validation run, or interleaved blocks of
    the estimation run) and mark standstill and creeping rows (the estimation run's speed
    thresholds for both)."""
    s, pre_info = _estimation_signals(est, cfg, held_out=val is None)
    creep = min(cfg.creep_fraction, cfg.rest_fraction) * s.v_scale

    def creeping(sig: Signals, rows: Array) -> Array:
        return rows & sig.moving_above(creep)

    if val is not None:
        v = Signals(on_the_same_turn(est, val), s.pre, q_range=s.q_range, rest_speed=s.rest_speed)
        e_rows, v_rows = ~s.in_gap, ~v.in_gap
        return Split(s, e_rows, v, v_rows, val.source, est_creep=creeping(s, e_rows), val_creep=creeping(v, v_rows), preprocessing=pre_info)
    val_mask, blocks = _held_out_blocks(s.n_rows, cfg)
    e_rows, v_rows = ~val_mask & ~s.in_gap, val_mask & ~s.in_gap
    return Split(s, e_rows, s, v_rows, f"{est.source} ({blocks})", est_creep=creeping(s, e_rows), val_creep=creeping(s, v_rows),
                 preprocessing=pre_info)


# ------------------------------------------------------------------------------------------
# Statistics


#: Cells the travel is cut into to tell which of a fold's rows lie where the other folds have
#: been (finer than the shapes the position bases follow).
CV_TRAVEL_CELLS = 64


def _cv_sse(X: Array, y: Array, folds: int, q: Array | None = None) -> float:
    """Blocked K-fold cross-validated SSE, from per-fold normal equations (columns scaled).

    With the rows' positions ``q``, a fold is scored only on its rows within the travel the other
    folds cover (:data:`CV_TRAVEL_CELLS` cells of it): a run whose motion changes over time (a
    sweep's wide first cycles) leaves a fold with travel the others never saw, where a position
    basis fitted without it can only guess, and the choice between bases would reward the one
    that guesses best, not the one that fits.  When that leaves fewer than half the rows (a run
    that crosses its travel once), every row is scored."""
    n = y.size
    scale = np.sqrt((X**2).sum(axis=0))
    scale[scale == 0] = 1.0
    Xs = X / scale
    idx = np.minimum((np.arange(n) * folds) // n, folds - 1)
    scored = np.ones(n, dtype=bool)
    if q is not None and np.ptp(q) > 0:
        cell = np.minimum(((q - q.min()) / np.ptp(q) * CV_TRAVEL_CELLS).astype(int), CV_TRAVEL_CELLS - 1)
        for k in range(folds):
            covered = np.bincount(cell[idx != k], minlength=CV_TRAVEL_CELLS) > 0
            scored[idx == k] = covered[cell[idx == k]]
        if scored.sum() < 0.5 * n:
            scored[:] = True
    G = [(Xs[idx == k].T @ Xs[idx == k], Xs[idx == k].T @ y[idx == k]) for k in range(folds)]
    GT = sum(g for g, _ in G)
    bT = sum(b for _, b in G)
    ridge = 1e-10 * np.trace(GT) / GT.shape[0]
    sse = 0.0
    for k in range(folds):
        A = GT - G[k][0] + ridge * np.eye(GT.shape[0])
        if not np.all(np.isfinite(A)):
            raise np.linalg.LinAlgError("non-finite normal equations")
        theta = _solve(A, bT - G[k][1])
        rows = (idx == k) & scored
        r = y[rows] - Xs[rows] @ theta
        sse += float(r @ r)
    return sse


def _solve(A: Array, b: Array) -> Array:
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


# ------------------------------------------------------------------------------------------
# Models


def _fit(m: LinearModel, split: Split) -> LinearModel:
    return m.fit(split.est, split.est_fit)


def _cv(m: LinearModel, split: Split, cfg: LoopConfig, by_travel: bool | None = None) -> float:
    """Blocked cross-validated SSE on the moving estimation rows.

    A model with a position basis (``by_travel``, by default whether ``m`` has one) is scored only
    where the folds share the travel (:func:`_cv_sse`): a position basis can only guess travel it
    has not seen.  Other models are scored on every row: a time effect (a warm-up) may show most
    at the start of a run, whose travel the later folds need not cover.  Two models compared with
    each other must be scored alike."""
    X = m.X(split.est)[split.est_fit]
    q = split.est.rows["q"][split.est_fit] if (has_position_basis(m) if by_travel is None else by_travel) else None
    return _cv_sse(X, split.est.y[split.est_fit], cfg.inner_folds, q)


def _sse(m: LinearModel, split: Split) -> float:
    r = (split.est.y - m.predict(split.est))[split.est_fit]
    return float(r @ r)


def _with_delay(m: LinearModel, delay: float, dt: float) -> LinearModel:
    out = m.copy()
    out.delay = float(delay)
    out.extras.pop("sampling_hold_s", None)
    if delay > 0:
        # what the core's zero-order hold already simulates: the axis model's delay is the rest
        out.extras["sampling_hold_s"] = 0.5 * dt
    return out


def _without(m: LinearModel, effect: str, dt: float) -> LinearModel:
    """``m`` without one of its effects (unfitted); without ``input_delay`` the force is not shifted."""
    if effect == "input_delay":
        out = _with_delay(m, 0.0, dt)
    else:
        out = m.copy()
        out.terms = [t for t in out.terms if t.name != effect]
    out.effects = [e for e in out.effects if e != effect]
    return out


def _reduced(m: LinearModel, effect: str, dt: float) -> LinearModel:
    """What an effect of ``m`` is tested against (unfitted): ``m`` without it, but with the part
    of its term that is no evidence for it on its own (:attr:`Effect.null`)."""
    out = _without(m, effect, dt)
    eff = CATALOGUE.get(effect)
    if eff is not None and eff.null is not None:
        out.terms.append(eff.null(next(t for t in m.terms if t.name == effect)))
    return out


def _replace_term(m: LinearModel, term: Term) -> LinearModel:
    out = m.copy()
    out.terms = [term if t.name == term.name else t for t in out.terms]
    return out


def baseline_physics(m: LinearModel, split: Split) -> dict[str, float]:
    """The baseline's physical parameters as ``m`` has them: the mass, the viscous coefficient,
    and the Coulomb level its whole friction amounts to (every friction term's force projected,
    on the moving estimation rows, on ``sign(qd)`` and ``qd``): a Stribeck curve, blocks, a drift
    or heating change how the friction is split, not how large it is."""
    S, rows = split.est, split.est_fit
    assert m.theta is not None
    theta = dict(zip(m.param_names, m.theta))
    out: dict[str, float] = {}
    if "M" in theta:
        out["M"] = float(theta["M"])
    if "Fv" in theta:
        out["Fv"] = float(theta["Fv"])
    names = [t.name for t in m.terms]
    if "coulomb" in names and "viscous" in names:
        steps = m.delay / S.dt
        fric = m.term_force(S, FRICTION_TERMS)
        B = np.column_stack([term_rows(BASE_TERMS["coulomb"], S, steps), term_rows(BASE_TERMS["viscous"], S, steps)])[rows]
        c = np.linalg.lstsq(B, fric[rows], rcond=None)[0]
        out["Fc"] = float(c[0])
    return out


def _plausibility(base_phys: dict[str, float], base_std: dict[str, float], m: LinearModel, split: Split, cfg: LoopConfig,
                  level_checked: bool = True, level_reference: float | None = None) -> tuple[dict[str, Any], str | None]:
    """Baseline parameters before (the baseline's) and with this step, and why they are
    implausible (``None`` when they are not).

    The mass and the viscous coefficient must stay physical: not below -3 standard errors of the
    baseline's (a small inertia behind a large friction, a robot joint's, is resolved no better),
    unless the baseline already had them there and the step brings them closer to physical (a
    Stribeck hump with a long tail left the baseline a viscous coefficient of -181 N s/m, and the
    hump -27: it does not corrupt the baseline, it mends part of what the baseline got wrong).  They may move a lot: the baseline absorbs whatever a missing effect correlates
    with (a spring ``k q`` looks like ``-k/w^2 qdd`` on an oscillation, a delay shifts force onto
    ``qdd`` and ``qd``), and the right effect gives it back.  The Coulomb level is what the axis
    slides at, a level every trajectory shows: an effect that lowers the effective level below
    ``1 / max_parameter_ratio`` of the baseline's explains friction away instead of adding to it.
    One that raises it gives back friction the baseline had lost to a force anti-correlated with
    ``sign(qd)`` on that run (an offset on a run that moves more one way, a cable's pull): the
    right effect does that, and the mass and viscous coefficient stay checked.  A baseline whose
    own mass or viscous coefficient is unphysical has absorbed a missing effect, and its level is
    no reference: a step that makes both physical may lower the level, not below 3 of its standard
    errors (a rotary joint's gravity the baseline took into twice the Coulomb level and a
    negative viscous coefficient).  ``level_checked=False`` for a step whose entering effects are
    all even in the speed (``Effect.even_in_speed``): a fall of the level is then the baseline's
    share of that force given back (a viscous asymmetry on a run that moves faster one way took
    the level from the rig's 3.2 N to 7.5 N).  Once such an effect is in the model, the level it
    left (``level_reference``, :func:`_level_reference`) is what later steps may not halve."""
    now = baseline_physics(m, split)
    checked = [k for k in ("M", "Fv") if k in base_phys]
    mends = (any(base_phys[k] < -3.0 * base_std.get(k, 0.0) for k in checked)
             and all(now.get(k, -np.inf) >= -3.0 * base_std.get(k, 0.0) for k in checked))
    report: dict[str, Any] = {}
    why = None
    for k, b in base_phys.items():
        a = now.get(k, float("nan"))
        ratio = a / b if b else float("nan")
        report[k] = {"baseline": float(f"{b:.6g}"), "with_step": float(f"{a:.6g}"), "ratio": round(ratio, 4) if np.isfinite(ratio) else None}
        if why is not None or not np.isfinite(a):
            continue
        sd = base_std.get(k, 0.0)
        if k == "M" and a < -3.0 * sd and a < b:
            why = f"implausible baseline: the mass becomes {a:.4g} (negative)"
        elif k == "Fv" and a < -3.0 * sd and a < b:
            why = f"implausible baseline: the viscous coefficient becomes {a:.4g} (negative)"
        elif k == "Fc" and level_checked:
            ref = b if level_reference is None else level_reference
            fall = a / ref if ref else float("nan")
            if ref > 3.0 * sd and np.isfinite(fall) and fall < 1.0 / cfg.max_parameter_ratio and not (mends and a > 3.0 * sd):
                whose = "the baseline's" if level_reference is None else "the level the model's even-in-speed effects left"
                why = f"implausible baseline: the effective Coulomb level {ref:.4g} -> {a:.4g} (x{fall:.2f}, below 1/{cfg.max_parameter_ratio:g} of {whose})"
    return report, why


# ------------------------------------------------------------------------------------------
# Stages


@dataclass
class _State:
    """What the stages hand on: the current model, its errors, steps and findings."""

    split: Split
    chunk: int
    base: LinearModel
    base_err: tuple[float, float]
    base_phys: dict[str, float]
    base_std: dict[str, float]
    model: LinearModel
    err: tuple[float, float]
    alignment: dict[str, Any]
    steps: list[Step] = field(default_factory=list)
    findings: dict[str, list[Finding]] = field(default_factory=dict)
    tests: int = 0
    #: The split on the moving rows (what the baseline, the plausibility and the report use) and
    #: on the moving and creeping rows; ``split`` is one of them (:func:`_describe_rows`).
    moving_split: Split = field(default=None)  # type: ignore[assignment]
    creep_split: Split = field(default=None)  # type: ignore[assignment]

    def __post_init__(self) -> None:
        if self.moving_split is None:
            self.moving_split = self.split
        if self.creep_split is None:
            self.creep_split = self.split.creeping()


def _describe_rows(st: _State) -> None:
    """Fit and test on the rows the current model describes: the creeping rows are left out
    because the baseline's ``sign(qd)`` of a filtered velocity is noise there; once a creeping
    effect (pre-sliding, driven by the measured position) is in the model they join every fit
    and test, and leave again with it."""
    split = st.creep_split if any(CATALOGUE[e].creeping for e in st.model.effects if e in CATALOGUE) else st.moving_split
    if split is not st.split:
        st.split = split
        st.model = _fit(st.model, split)
        st.err = split.errors(st.model)


def _check_names(cfg: LoopConfig) -> list[str]:
    return list(cfg.effects) if cfg.effects is not None else list(CATALOGUE)


def stage_prepare(est: AxisData, val: AxisData | None, cfg: LoopConfig) -> tuple[Split, int]:
    """Stage 1: preprocessing, held-out rows, standstill; the held-out test's chunk length."""
    split = make_split(est, val, cfg)
    for name, rows, sig in (("estimation", split.est_fit, split.est), ("held-out", split.val_test, split.val)):
        if rows.sum() < 50:
            why = (f"{100.0 * sig.in_gap.mean():.0f} % of the rows lie in or next to gaps in the log (steps longer than {GAP_STEPS:g} median steps)"
                   if sig.in_gap.mean() > 0.5 else "the axis barely moves")
            raise IdentificationError(f"{sig.data.source}: only {int(rows.sum())} moving {name} rows; {why}")
    return split, chunk_rows(split, int(split.val_test.sum()))


def _align(model: LinearModel, split: Split, cfg: LoopConfig, st_align: dict[str, Any], after_round: int, chunk: int) -> LinearModel:
    """The timing alignment of ``model`` (fitted): a shift of the force within one sample, chosen
    by cross-validation on the estimation rows, kept when the held-out rows confirm it."""
    if not cfg.sampling_hold or "input_delay" in model.effects:
        return model
    dt = split.est.dt
    best: tuple[float, LinearModel] | None = None
    for f in ALIGNMENT_GRID:
        m = _with_delay(model, f * dt, dt)
        try:
            cv = _cv(m, split, cfg)
        except np.linalg.LinAlgError:
            continue
        if best is None or cv < best[0]:
            best = (cv, m)
    unshifted = _fit(_with_delay(model, 0.0, dt), split)
    shifted = _fit(best[1], split) if best is not None else unshifted
    h = heldout(split, unshifted, shifted, chunk) if shifted.delay > 0 else None
    applied = h is not None and h.p <= cfg.alpha and h.t >= cfg.t_threshold
    chosen = shifted if applied else unshifted
    e = split.errors(shifted)
    st_align["tests"].append({"after_round": after_round, "shift_s": round(float(shifted.delay), 9),
                              "t_heldout": round(h.t, 2) if h else None, "p_heldout": float(f"{h.p:.3g}") if h else None,
                              "estimation_error_pct": round(e[0], 4), "validation_error_pct": round(e[1], 4), "applied": bool(applied)})
    st_align["applied"] = bool(applied)
    st_align["shift_s"] = float(chosen.delay)
    return chosen


def _creeping(st: _State) -> _State:
    """``st`` as a creeping effect is judged: fits and tests on the moving and creeping rows,
    the current model fitted there."""
    if st.split is st.creep_split:
        return st
    return replace(st, split=st.creep_split, model=_fit(st.model.copy(), st.creep_split))


def stage_baseline(split: Split, chunk: int, cfg: LoopConfig) -> _State:
    """Stage 2: the baseline on the moving estimation rows, then the timing alignment."""
    S = split.est
    base = _fit(LinearModel([BASE_TERMS[b] for b in cfg.baseline]), split)
    base_err = split.errors(base)
    p = base.params()
    if _opposite_sign(p):
        raise IdentificationError(f"{S.data.source}: the force has the opposite sign to the motion: the baseline's inertia and Coulomb "
                                  f"friction both come out negative (M = {p['M']['value']:.4g} {parameter_unit('M', S.data.rotary)}, "
                                  f"Fc = {p['Fc']['value']:.4g} {parameter_unit('Fc', S.data.rotary)}); gmsfric "
                                  "expects the force applied to the axis, with the sign of the motion it drives: negate the force column "
                                  "(or the drive gain)")
    phys = baseline_physics(base, split)
    std = {k: p[k]["std"] for k in ("M", "Fc", "Fv") if k in p}
    alignment: dict[str, Any] = {}
    if cfg.sampling_hold:
        alignment = {"sampling_hold_s": 0.5 * S.dt, "applied": False, "shift_s": 0.0,
                     "rule": "force shifted by 0 to 1 sample (grid of 0.1 sample, chosen by cross-validation on the estimation rows), "
                             "kept when the held-out test confirms it; the core simulates half a sample (its hold), the rest is the axis model's delay",
                     "tests": []}
    st = _State(split, chunk, base, base_err, phys, std, base, base_err, alignment)
    st.model = _align(base, split, cfg, alignment, 0, chunk)
    st.err = split.errors(st.model)
    return st


def _opposite_sign(params: dict[str, dict[str, Any]]) -> bool:
    """Whether the baseline's inertia and Coulomb friction are both negative beyond three
    standard errors: the force then opposes what drives the axis (a reaction, or a drive gain of
    the other sign), which no effect can explain."""
    def negative(name: str) -> bool:
        v = params.get(name)
        return v is not None and v["value"] < 0 and (v["std"] is None or not v["value"] + 3.0 * v["std"] >= 0)
    return negative("M") and negative("Fc")


def _residual_rows(st: _State, cfg: LoopConfig) -> tuple[dict[str, Finding], Array]:
    S, rows = st.split.est, st.split.est_fit
    y_hat = st.model.predict(S)
    r = S.y - y_hat
    fnd = {f.variable: f for f in _analyse_rows(S, rows, r, y_hat, cfg.seed)}
    return fnd, np.where(rows, r, np.nan)


def _best_variant(eff: Effect, model: LinearModel, st: _State, cfg: LoopConfig, r_est: Array, prog: Progress | None = None) -> tuple[LinearModel | None, str | None]:
    """The effect's variant chosen on the moving estimation rows (:func:`_best_variant_on`), and
    why the last invalid one was refused.  For an effect :attr:`Effect.chosen_clear_of_reversals`
    that has none there (a probe fits best), the choice is made again on the rows clear of
    reversals and stops, and that variant stands when its fit on all rows is physical too.  The
    chosen variant then meets the effect's rivals (:func:`_rival_fits_better`)."""
    best, why = _best_variant_on(eff, model, st.split, cfg, r_est, prog)
    if best is None and eff.chosen_clear_of_reversals and (clear := clear_split(st.split)) is not None:
        alt, _ = _best_variant_on(eff, model, clear, cfg, r_est, prog)
        if alt is None:
            return None, f"{why}; clear of reversals and stops too" if why else why
        # chosen on part of the rows, it is fitted and tested on all of them: physical there too
        w = eff.check(_fit(alt.copy(), st.split), st.split.est)
        if w is not None:
            return None, f"{why}; chosen clear of reversals and stops, fitted on all rows: {w}" if why else w
        best = alt
    if best is not None and (rival := _rival_fits_better(eff, model, best, st.split, cfg, r_est)) is not None:
        return None, rival
    return best, why


def _rival_fits_better(eff: Effect, model: LinearModel, chosen: LinearModel, split: Split, cfg: LoopConfig, r_est: Array) -> str | None:
    """Why the effect's ``chosen`` variant gives way to one of its rivals (:attr:`Effect.rivals`),
    or ``None`` when none cross-validates clearly better (:data:`RIVAL_MARGIN`) on the moving
    estimation rows."""
    if eff.rivals is None:
        return None
    by_travel = has_position_basis(chosen)
    cv = _cv(chosen, split, cfg, by_travel)
    for rival, what in eff.rivals(model, chosen, split.est, r_est):
        try:
            cv_rival = _cv(rival, split, cfg, by_travel)
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            continue
        if cv > 0 and cv_rival <= RIVAL_MARGIN * cv:
            return f"{what} fits the estimation rows better ({cv_rival / cv:.2g} of its cross-validated error)"
    return None


def _best_variant_on(eff: Effect, model: LinearModel, split: Split, cfg: LoopConfig, r_est: Array,
                     prog: Progress | None = None) -> tuple[LinearModel | None, str | None]:
    """The effect's variant with the smallest cross-validated error on ``split``'s estimation rows
    (only physically valid fits), and why the last invalid one was refused.  An effect's
    probe variants (:attr:`Effect.probe`) are cross-validated too, and none is returned when one
    of them is better than the best valid variant (refined first when the effect is
    :attr:`Effect.refine`-d); a contested variant (:attr:`Effect.contested`) counts as valid when its
    error is at most :data:`CONTESTED_MARGIN` times the best probe's."""
    best: tuple[float, LinearModel] | None = None
    best_invalid: tuple[float, str] | None = None
    contested: tuple[float, LinearModel] | None = None
    why: str | None = None
    for m in eff.variants(model, split.est, r_est):
        try:
            if eff.physical is not None:
                w = eff.check(_fit(m, split), split.est)
                if w is not None:
                    why = w
                    is_probe = eff.probe is not None and eff.probe(m.params(), split.est)
                    if is_probe or (eff.contested is not None and eff.contested(m.params(), split.est)):
                        cv_bad = _cv(m, split, cfg)
                        if is_probe and (best_invalid is None or cv_bad < best_invalid[0]):
                            best_invalid = (cv_bad, w)
                        if not is_probe and (contested is None or cv_bad < contested[0]):
                            contested = (cv_bad, m)
                    continue
            cv = _cv(m, split, cfg)
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            continue
        if best is None or cv < best[0]:
            best = (cv, m)
        if prog is not None:
            prog.update(note=f"{eff.name}")
    if contested is not None and best_invalid is not None and contested[0] <= CONTESTED_MARGIN * best_invalid[0] and (best is None or contested[0] < best[0]):
        best = contested
    if best is not None and eff.name == "input_delay":
        best = _refine_delay(best, split, cfg)
    if best is not None and eff.refine is not None:
        # refined before it meets the probes: a resonance between the grid's frequencies and
        # damping ratios fits far worse than at its own (an outside audit's rig: 0.46 of the
        # baseline's error at the nearest grid point, 0.29 at the planted one, a probe 0.39)
        best, beyond = _refine_hyper(eff, best, split, cfg)
        if beyond is not None:
            return None, f"{beyond}; the refined fit goes there"
    if best_invalid is not None and (best is None or best_invalid[0] < best[0]):
        return None, f"{best_invalid[1]}; that fits the estimation rows best"
    return (best[1], why) if best is not None else (None, why)


#: Fewest estimation rows clear of reversals and stops on which an effect's parameters are chosen
#: again (:attr:`Effect.chosen_clear_of_reversals`).
MIN_CHOICE_ROWS = 200


def clear_split(split: Split) -> Split | None:
    """``split`` with its estimation rows cut to those clear of reversals and stops (``None`` when
    fewer than :data:`MIN_CHOICE_ROWS`)."""
    rows = clear_rows(split).est
    if rows.sum() < MIN_CHOICE_ROWS:
        return None
    return replace(split, est_fit=rows, est_creep=rows, label="moving rows clear of reversals and stops")


#: First step of the refinement of a nonlinear parameter, in its logarithm (about 10 %).
REFINE_STEP = 0.1


def _refine_hyper(eff: Effect, best: tuple[float, LinearModel], split: Split, cfg: LoopConfig) -> tuple[tuple[float, LinearModel], str | None]:
    """The effect's nonlinear parameters refined from the best grid variant (Nelder-Mead on their
    logarithms, within the effect's bounds, on the same cross-validated error); the grid variant
    stays when nothing better is found or the refined fit is not physical.  The bounds may reach
    into the probes' range: a refined fit that ends there is returned with the reason it is not
    physical (the data prefer what the effect is not, as when a probe wins on the grid)."""
    cv0, m0 = best
    term = next(t for t in m0.terms if t.name == eff.name)
    if not all(h > 0 for h in term.hyper):
        return best, None  # a zero marks a variant of another form (a linear drift), not a point of the range
    bounds = np.log(np.asarray(eff.refine(split.est), dtype=float))  # type: ignore[misc]

    def variant(z: Array) -> LinearModel:
        return _replace_term(m0, term.with_hyper(tuple(float(v) for v in np.exp(np.clip(z, bounds[:, 0], bounds[:, 1])))))

    def objective(z: Array) -> float:
        try:
            return _cv(variant(z), split, cfg)
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            return np.inf

    z0 = np.clip(np.log(np.asarray(term.hyper, dtype=float)), bounds[:, 0], bounds[:, 1])
    # the first simplex steps every parameter by REFINE_STEP in its logarithm, into the range:
    # scipy's default (5 % of each coordinate) depends on the unit and leaves a parameter whose
    # logarithm is zero (a Stribeck exponent of 1) where it started
    step = np.where(z0 + REFINE_STEP <= bounds[:, 1], REFINE_STEP, -REFINE_STEP)
    simplex = np.vstack([z0, z0 + np.diag(step)])
    res = optimize.minimize(objective, z0, method="Nelder-Mead",
                            options={"maxfev": 60, "xatol": 1e-3, "fatol": 1e-6 * cv0, "initial_simplex": simplex})
    if not (np.isfinite(res.fun) and res.fun < cv0):
        return best, None
    m = variant(res.x)
    if eff.physical is not None and (why := eff.check(_fit(m, split), split.est)) is not None:
        beyond = eff.probe is not None and eff.probe(m.params(), split.est)
        return best, (why if beyond else None)
    return (float(res.fun), m), None


#: Precision (samples) to which a delay is refined between its grid neighbours.
DELAY_REFINE_TOL = 0.02


def _refine_delay(best: tuple[float, LinearModel], split: Split, cfg: LoopConfig) -> tuple[float, LinearModel]:
    """The best grid delay refined between its neighbours on :data:`DELAY_STEPS` (bounded scalar
    search on the same cross-validated error), never below the grid's first delay.  The grid is a
    sample or more apart beyond four samples, and a delay off by half a sample leaves a residual
    like the force's derivative, which a resonance at the top of its range then takes up (an
    outside audit's 1 kHz rig: 3.5 ms chosen for 3.33 ms, then a 40 Hz "compliance")."""
    cv0, m0 = best
    dt = split.est.dt
    steps0 = m0.delay / dt
    k = int(np.argmin(np.abs(DELAY_STEPS - steps0)))
    lo, hi = float(DELAY_STEPS[max(k - 1, 0)]), float(DELAY_STEPS[min(k + 1, DELAY_STEPS.size - 1)])
    if not hi > lo:
        return best

    def objective(steps: float) -> float:
        try:
            return _cv(_with_delay(m0, steps * dt, dt), split, cfg)
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            return np.inf

    res = optimize.minimize_scalar(objective, bounds=(lo, hi), method="bounded", options={"xatol": DELAY_REFINE_TOL, "maxiter": 20})
    if not (np.isfinite(res.fun) and res.fun < cv0):
        return best
    return float(res.fun), _with_delay(m0, float(res.x) * dt, dt)


def _joint_refit(st: _State, cfg: LoopConfig, rnd: int) -> None:
    """Choose every accepted effect's grid parameters again given the others (in the order they
    entered), then the timing alignment, then the grid parameters again in passes until a pass no
    longer lowers the cross-validated error (at most :data:`JOINT_REFIT_PASSES` in all)."""
    model = _fit(_rechoose(st.model, list(st.model.effects), st, cfg), st.split)
    model = _align(model, st.split, cfg, st.alignment, rnd, st.chunk) if st.alignment else model
    cv = _cv(model, st.split, cfg)
    for _ in range(JOINT_REFIT_PASSES - 1):
        cand = _fit(_rechoose(model, list(model.effects), st, cfg), st.split)
        cv_cand = _cv(cand, st.split, cfg)
        if not cv_cand < (1.0 - JOINT_REFIT_TOL) * cv:
            break
        model, cv = cand, cv_cand
    st.model = model
    st.err = st.split.errors(st.model)


def _rechoose(model: LinearModel, names: Sequence[str], st: _State, cfg: LoopConfig) -> LinearModel:
    """``model`` with the grid parameters of the effects ``names`` chosen again, one after the
    other, each given all the other terms (smallest cross-validated error on the estimation rows,
    physically valid fits only)."""
    dt = st.split.est.dt
    for name in names:
        # a creeping effect's grid parameters are chosen where it is judged
        split = st.creep_split if CATALOGUE[name].creeping else st.split
        if name == "input_delay":
            reduced = _without(model, name, dt)
        else:
            reduced = model.copy()
            reduced.terms = [t for t in model.terms if t.name != name]
        reduced = _fit(reduced, split)
        r = split.est.y - reduced.predict(split.est)
        variants = CATALOGUE[name].variants(reduced, split.est, np.where(split.est_fit, r, np.nan))
        if len(variants) < 2:
            continue
        cur_cv = _cv(model, split, cfg)
        eff = CATALOGUE[name]
        for v in variants:
            cand = _with_delay(model, v.delay, dt) if name == "input_delay" else _replace_term(model, next(t for t in v.terms if t.name == name))
            try:
                if eff.physical is not None and eff.check(_fit(cand, split), split.est) is not None:
                    continue
                cv = _cv(cand, split, cfg)
            except (IdentificationError, np.linalg.LinAlgError, ValueError):
                continue
            if cv < cur_cv:
                cur_cv, model = cv, cand
        if name == "input_delay":
            cur_cv, model = _refine_delay((cur_cv, model), split, cfg)
        if eff.refine is not None:
            (cur_cv, model), _ = _refine_hyper(eff, (cur_cv, model), split, cfg)
    return model


def _backward(st: _State, cfg: LoopConfig, rnd: int, newest: str) -> None:
    """Test every earlier effect again given all the others; one that no longer earns its place
    (``p > alpha`` or less than the minimum gain on the held-out rows) leaves the model."""
    dt = st.split.est.dt
    changed = True
    while changed:
        changed = False
        split = st.split
        for name in [e for e in st.model.effects if e != newest]:
            reduced = _fit(_without(st.model, name, dt), split)
            if st.alignment and name == "input_delay":
                reduced = _align(reduced, split, cfg, st.alignment, rnd, st.chunk)
            null = _fit(_reduced(st.model, name, dt), split) if CATALOGUE[name].null is not None else reduced
            h = heldout(split, null, st.model, st.chunk, effect=name)
            if h.p <= cfg.alpha and h.gain >= cfg.min_gain:
                continue
            for s in st.steps:
                if s.accepted and s.effect == name:
                    s.accepted = False
                    s.evidence["removed_in_round"] = rnd
                    s.reason += (f"; removed in round {rnd}: given the others (with {newest}) its held-out gain is "
                                 f"{100 * h.gain:.2f} % (t = {h.t:.2f}, p = {h.p:.2g})")
            st.model = reduced
            st.err = split.errors(reduced)
            _describe_rows(st)
            changed = True
            break


def stage_select(st: _State, cfg: LoopConfig, names: list[str]) -> None:
    """Stage 3: rounds of forward selection (corrected held-out test, competition on the same
    held-out rows), joint refit and backward elimination."""
    split = st.split
    far = clear_rows(split)  # the rows do not change from round to round
    rnd = 0
    with Progress("gmsfric loop", enabled=cfg.progress) as prog:
        while len(st.model.effects) < cfg.max_effects:
            rnd += 1
            fnd, r_est = _residual_rows(st, cfg)
            if rnd == 1:
                st.findings["baseline_estimation"] = list(fnd.values())
            cands: list[tuple[float, Effect, LinearModel]] = []
            nulls: dict[str, LinearModel] = {}
            applicable = [CATALOGUE[n] for n in names if CATALOGUE[n].applicable(st.model)]
            creep = _creeping(st) if any(eff.creeping for eff in applicable) else st
            for eff in applicable:
                prog.update(note=f"round {rnd}: {eff.name}")
                se = creep if eff.creeping else st
                m, why = _best_variant(eff, se.model, se, cfg, r_est, prog)
                if m is not None:
                    m, nulls[eff.name], gain_cv = _candidate(m, eff.name, list(st.model.effects), se, cfg)
                    cands.append((gain_cv, eff, m))
                elif why is not None:
                    f = fnd.get(eff.evidence)
                    ev0: dict[str, Any] = {"residual_test": f.as_dict()} if f is not None else {}
                    st.steps.append(Step(rnd, eff.name, False, f"no physically valid fit ({why})", ev0, float("nan"), float("nan"), {}))
            screened = sum(_screened(creep if eff.creeping else st, cfg, eff, m, nulls[eff.name], gain_cv) for gain_cv, eff, m in cands)
            level = cfg.level(rnd, screened)
            passing: list[tuple[float, Step, LinearModel]] = []
            for gain_cv, eff, m in sorted(cands, key=lambda c: -c[0]):
                step, h, _ = _test_candidate(creep if eff.creeping else st, cfg, rnd, eff, m, nulls[eff.name], gain_cv, level, far, fnd)
                step.evidence["level_shared_by"] = screened
                st.steps.append(step)
                if not step.reason:
                    passing.append((h.ranking_gain, step, m))
            if not passing:
                if len(st.model.effects) + 2 <= cfg.max_effects and _pair_step(st, cfg, rnd, cands, far, fnd, prog):
                    rnd += 1  # the pair spent the next round's share of the level
                    continue
                # the pairs spent (or could have spent) round rnd + 1's share: exchanges take the next
                if _exchange_step(st, cfg, rnd + 2, names, far, fnd, prog):
                    rnd += 2
                    continue
                break
            passing.sort(key=lambda c: -c[0])
            _, step, m = passing[0]
            step.accepted = True
            mv = step.evidence["moving_rows_error_pct"]["validation"]
            step.reason = (f"held-out error {mv / (1.0 - step.evidence['validation_gain']):.3f} -> {mv:.3f} % on {step.evidence['judged_on']} (t = {step.evidence['t_heldout']:.1f}, "
                           f"p = {step.evidence['p_heldout']:.2g} <= {level:.2g}), BIC {step.evidence['delta_bic']:+.1f}")
            for _, other, _ in passing[1:]:
                other.reason = f"passes, but {step.effect} gains more on the same held-out rows this round"
            st.model = m
            st.err = split.errors(m)
            _describe_rows(st)
            _joint_refit(st, cfg, rnd)
            _backward(st, cfg, rnd, step.effect)
            step.parameters = st.model.params() if step.effect in st.model.effects else step.parameters


def _candidate(m: LinearModel, effect: str, others: list[str], st: _State, cfg: LoopConfig) -> tuple[LinearModel, LinearModel, float]:
    """A candidate variant ``m`` of ``effect`` on top of the accepted ``others``:
    the candidate model, what it is tested against (fitted) and its cross-validated gain.  The
    others' grid parameters were chosen without the effect, which may have pulled them (a
    resonance's frequency absorbing a drift): they are chosen again with it, then its own given
    theirs; and again without it from there, so that it is credited only with what it enables."""
    null = _tested_against(m, effect, st)
    if others:
        m = _rechoose(m, others + [effect], st, cfg)
        null = _rechoose(_tested_against(m, effect, st), others, st, cfg)
    null = _fit(null, st.split)
    by_travel = has_position_basis(m, null)
    return m, null, sse_gain(_cv(m, st.split, cfg, by_travel), _cv(null, st.split, cfg, by_travel))


def _delta_bic(m: LinearModel, null: LinearModel, split: Split) -> float:
    """BIC of fitted ``m`` minus that of fitted ``null`` on the moving estimation rows."""
    n_est = int(split.est_fit.sum())
    return float(n_est * np.log(_sse(m, split) / _sse(null, split)) + (m.n_params - null.n_params) * np.log(n_est))


def _level_reference(st: _State) -> float | None:
    """The Coulomb level a step may not halve when the current model holds an effect even in the
    speed: the lower of the baseline's and the current model's (that effect gave back what the
    baseline had taken into its level); ``None`` (the baseline's) otherwise."""
    if "Fc" not in st.base_phys or not any(e in CATALOGUE and CATALOGUE[e].even_in_speed for e in st.model.effects):
        return None
    now = baseline_physics(st.model, st.moving_split).get("Fc", float("nan"))
    return min(st.base_phys["Fc"], now) if np.isfinite(now) else None


def _screened(st: _State, cfg: LoopConfig, eff: Effect, m: LinearModel, null: LinearModel, gain_cv: float) -> bool:
    """Whether a candidate ``m`` of ``eff`` (tested against fitted ``null``) passes every check
    made on the estimation run alone: a cross-validated gain (``min_estimation_gain``), a lower BIC
    and a plausible baseline.  Only those candidates can enter, so only they share a round's level."""
    _fit(m, st.split)
    return (cfg.gains_on_estimation(gain_cv) and _delta_bic(m, null, st.split) < 0
            and _plausibility(st.base_phys, st.base_std, m, st.moving_split, cfg, not eff.even_in_speed, _level_reference(st))[1] is None)


def _test_candidate(st: _State, cfg: LoopConfig, rnd: int, eff: Effect, m: LinearModel, null: LinearModel, gain_cv: float,
                    level: float, far: ClearRows, fnd: dict[str, Finding]) -> tuple[Step, HeldOut, HeldOut]:
    """The tests of a candidate model ``m`` whose effect ``eff`` is tested against ``null``
    (fitted): its step (rejected; ``reason`` empty when every test passes), the held-out test
    against the null and the one against the current model."""
    split = st.split
    _fit(m, split)
    e_est, e_val = split.errors(m)
    h = heldout(split, null, m, st.chunk, effect=eff.name)
    # the whole must also beat the current model (the others chosen again without
    # the effect, or its null part, may predict the held-out run worse than it)
    h_cur = heldout(split, st.model, m, st.chunk, effect=eff.name) if st.model.effects or eff.null is not None else h
    far_level = eff.level_clear_of_reversals(m, level, cfg.alpha)
    h_far = heldout_clear(split, null, m, st.chunk, far, eff.refit_clear_of_reversals) if far_level is not None else None
    dbic = _delta_bic(m, null, split)
    change, implausible = _plausibility(st.base_phys, st.base_std, m, st.moving_split, cfg, not eff.even_in_speed, _level_reference(st))
    ev: dict[str, Any] = {}
    f = fnd.get(eff.evidence)
    if f is not None:
        ev["residual_test"] = f.as_dict()
    ev.update(cv_gain=round(gain_cv, 5), validation_gain=round(h.gain, 5),
              moving_rows_error_pct={"estimation": round(split.errors_moving(m)[0], 4), "validation": round(h.error_after, 4)},
              t_heldout=round(h.t, 2), p_heldout=float(f"{h.p:.3g}"),
              level=float(f"{level:.3g}"), delta_bic=round(float(dbic), 1), baseline_parameters=change)
    ev["judged_on"] = f"{split.label} rows" + (" within the estimation travel" if h.within_travel else "")
    if eff.null is not None:
        ev["tested_against"] = f"the current model plus {', '.join(eff.null(next(t for t in m.terms if t.name == eff.name)).param_names)} alone"
    reasons = []
    if not gain_cv > 0:  # NaN too (both models' cross-validated errors zero): no gain
        reasons.append("no cross-validated gain on estimation data")
    elif not cfg.gains_on_estimation(gain_cv):
        reasons.append(f"cross-validated error gain on estimation data {100 * error_gain(gain_cv):.2f} % "
                       f"< {100 * cfg.min_estimation_gain:.2f} %")
    if h.gain < cfg.min_gain:
        reasons.append(f"held-out error gain {100 * h.gain:.2f} % < {100 * cfg.min_gain:.2f} %")
    if h.p > level or h.t < cfg.t_threshold:
        reasons.append(f"held-out gain within noise (t = {h.t:.2f}, p = {h.p:.2g} > {level:.2g})" if h.p > level
                       else f"held-out t = {h.t:.2f} < {cfg.t_threshold}")
    if h_cur is not h:
        ev["t_heldout_against_current_model"] = round(h_cur.t, 2)
        if h_cur.p > level or h_cur.gain < cfg.min_gain:
            reasons.append(f"the model with it is no better than the current model on held-out data (gain "
                           f"{100 * h_cur.gain:.2f} %, t = {h_cur.t:.2f}, p = {h_cur.p:.2g})")
    if far_level is not None and h_far is None:
        reasons.append("too few rows clear of reversals and stops to confirm it")
    far_reason = None
    if h_far is not None and far_level is not None:
        ev["t_heldout_away_from_reversals"] = round(h_far.t, 2)
        ev["validation_gain_away_from_reversals"] = round(h_far.gain, 5)
        # a whole-motion effect must also gain there by the minimum gain asked of it on all rows
        sized = eff.whole_motion and not eff.consistency_only
        if h_far.p > far_level or (sized and (h_far.t < cfg.t_threshold or h_far.gain < cfg.min_gain)):
            far_reason = (f"not confirmed away from reversals (gain {100 * h_far.gain:.2f} %, t = {h_far.t:.2f}, p = {h_far.p:.2g}; "
                          f"level {far_level:.2g}" + (f", minimum gain {100 * cfg.min_gain:.2f} %): " if sized else "): ")
                          + ("it acts on the whole motion, and a gain only where the axis reverses or sticks is the switch of friction"
                             if eff.whole_motion else "a dip only where the axis reverses or sticks is the switch of friction seen through the filters"))
            reasons.append(far_reason)
    if dbic >= 0:
        reasons.append(f"BIC does not decrease ({dbic:+.1f})")
    # Refused only because the rows clear of reversals confirm it at no more than the nominal
    # alpha, a delay that beats a freely timed switch is added when those rows keep a fair share
    # of its gain, and otherwise reported as unconfirmed.
    clear_consistent = far_reason is not None and h_far is not None and h_far.p <= cfg.alpha and reasons == [far_reason]
    if eff.name == "input_delay" and (not reasons or clear_consistent):
        tone = _a_single_tone(split, null, m, st.chunk, level, ev)
        h_sw, refuted = _beyond_a_free_switch(m, null, split, cfg, st.chunk)
        ev.update(t_heldout_beyond_a_free_switch=round(h_sw.t, 2), validation_gain_beyond_a_free_switch=round(h_sw.gain, 5))
        if refuted:
            ev["free_switch_refuted_on_held_out_data"] = True
        if tone is not None:
            reasons.append(tone)
        elif not _beats_a_free_switch(h_sw, h, level, cfg, share_may_relax=not clear_consistent):
            reasons.append(f"no better on held-out data than the switch of friction at a time of its own (gain "
                           f"{100 * h_sw.gain:.2f} %, t = {h_sw.t:.2f}, p = {h_sw.p:.2g}): a contact that sticks at "
                           "reversals makes the filtered velocity switch late, and a delay of the whole force absorbs that lag")
        elif clear_consistent and h_far.gain >= max(cfg.min_gain, DELAY_CLEAR_SHARE * h.gain):
            reasons.clear()
            ev["clear_of_reversals"] = (f"consistent at the nominal alpha, {100 * h_far.gain:.1f} % of the error there removed "
                                        f"(at least {DELAY_CLEAR_SHARE:.2g} of the gain on all rows), beyond a freely timed switch of friction")
        elif clear_consistent:
            ev["unconfirmed_clear_of_reversals"] = True
    if implausible is not None:
        if not reasons:
            # every test of the data passed: the report says so (``held_back`` diagnostic)
            ev["held_back_by_plausibility"] = True
        reasons.append(implausible)
    return Step(rnd, eff.name, False, "; ".join(reasons), ev, e_est, e_val, m.params(), m), h, h_cur


def _exchange_step(st: _State, cfg: LoopConfig, rnd: int, names: Sequence[str], far: ClearRows, fnd: dict[str, Finding],
                   prog: Progress) -> bool:
    """When nothing more enters, every accepted effect is tried replaced by every catalogue effect
    not in the model.  An effect can enter first as the nearest stand-in for another that the run
    correlates with it (a position-dependent force for a friction asymmetry, where the speed
    follows the position), and then keep the other out: given the stand-in, the other gains
    little.  The replacement is fitted on the model without the accepted effect, every grid
    parameter chosen again, and tested as an entering effect is (against the same model without
    it, at ``level(rnd, X)`` for the ``X`` exchanges tried that pass the estimation-only checks,
    :func:`_screened`); the model after the exchange must also beat the current one on held-out
    data and in cross-validated error.  The exchange that gains most on the current model is
    made, then joint refit and backward elimination.  Returns whether one was made.

    The other form of the accepted effect (:func:`~gmsfric.loop.effects.alternative_forms`)
    names no new phenomenon: it is tested at the nominal ``alpha`` rather than the family's share,
    and judged against the current model on the held-out run alone, since over the estimation
    run's pace the two forms' columns are nearly collinear (a heating rig, outside audit: heating
    beats the drift that entered first by 4-22 % of the held-out error, t = 2.4-5.0, while on
    drift rigs heating never beats the drift, t <= 0.3)."""
    split, dt = st.split, st.split.est.dt
    creep = _creeping(st) if any(CATALOGUE[n].creeping for n in names) else st
    trials: list[tuple[str, Effect, LinearModel, LinearModel, float]] = []
    for out in list(st.model.effects):
        base = _fit(_without(st.model, out, dt), split)
        r_est = np.where(split.est_fit, split.est.y - base.predict(split.est), np.nan)
        for name in names:
            eff = CATALOGUE[name]
            if name == out or name in st.model.effects or not eff.applicable(base):
                continue
            prog.update(note=f"round {rnd}: {name} for {out}")
            se = creep if eff.creeping else st
            m, _ = _best_variant(eff, base, se, cfg, r_est)
            if m is None:
                continue
            m, null, gain_cv = _candidate(m, name, list(base.effects), se, cfg)
            trials.append((out, eff, m, null, gain_cv))
    screened = sum(_screened(creep if eff.creeping else st, cfg, eff, m, null, gain_cv) for _, eff, m, null, gain_cv in trials)
    level = cfg.level(rnd, screened)
    best: tuple[float, Step, LinearModel, str] | None = None
    for out, eff, m, null, gain_cv in trials:
        se = creep if eff.creeping else st
        other_form = alternative_forms(out, eff.name)
        step, _, h_cur = _test_candidate(se, cfg, rnd, eff, m, null, gain_cv, cfg.alpha if other_form else level, far, fnd)
        step.evidence["replaces"] = out
        if other_form:
            step.evidence["other_form_of"] = out
        else:
            step.evidence["level_shared_by"] = screened
        by_travel = has_position_basis(m, se.model)
        if not other_form and not _cv(m, se.split, cfg, by_travel) < _cv(se.model, se.split, cfg, by_travel):
            step.reason = "; ".join(filter(None, [step.reason, f"no lower cross-validated error than the model with {out}"]))
        step.reason = step.reason and f"in place of {out}{' (its other form)' if other_form else ''}: {step.reason}"
        st.steps.append(step)
        if not step.reason and (best is None or h_cur.gain > best[0]):
            best = (h_cur.gain, step, m, out)
    if best is None:
        return False
    gain, step, m, out = best
    step.accepted = True
    step.reason = (f"replaces {out}: held-out error {100 * gain:.2f} % lower than with {out} (t = {step.evidence['t_heldout_against_current_model']:.1f}); "
                   f"given the others t = {step.evidence['t_heldout']:.1f}, p = {step.evidence['p_heldout']:.2g} <= {step.evidence['level']:.2g}, BIC {step.evidence['delta_bic']:+.1f}")
    for s in st.steps:
        if s.accepted and s.effect == out:
            s.accepted = False
            s.evidence["replaced_in_round"] = rnd
            s.reason += f"; replaced in round {rnd} by {step.effect}"
    st.model = m
    st.err = split.errors(m)
    _describe_rows(st)
    _joint_refit(st, cfg, rnd)
    _backward(st, cfg, rnd, step.effect)
    step.parameters = st.model.params() if step.effect in st.model.effects else step.parameters
    return True


def _tested_against(m: LinearModel, effect: str, st: _State) -> LinearModel:
    """What the ``effect`` of a candidate ``m`` is tested against (unfitted): ``m`` without it,
    the part of its term that is no evidence on its own kept (:func:`_reduced`), every other
    term as ``m`` has it, and the current model's timing alignment."""
    out = _reduced(m, effect, st.split.est.dt)
    if effect == "input_delay":
        out.delay, out.extras = st.model.delay, dict(st.model.extras)
    return out


def single_tone(split: Split, before: LinearModel, after: LinearModel, chunk: int) -> dict[str, float]:
    """Where on the held-out moving rows ``after`` gains on ``before``, by frequency: ``line_hz``,
    the frequency of the largest decrease of the residual's power; ``share``, the share of the
    whole decrease within :data:`TONE_HALF_WIDTH` of it (at least two bins either side);
    ``motion``, the share of the motion's (velocity's) power there; and ``t_off``, ``p_off``,
    the held-out chunk test of the two residuals with that line taken out of both."""
    rows = split.val_test
    if rows.sum() < 8:
        return dict(NO_LINE)  # too few rows to tell one line from the rest
    y = split.val.y
    r0 = np.where(rows, y - before.predict(split.val), 0.0)
    r1 = np.where(rows, y - after.predict(split.val), 0.0)
    qd = split.val.rows["qd"]
    v = np.where(rows, qd - qd[rows].mean(), 0.0)
    f = np.fft.rfftfreq(r0.size, split.val.dt * split.val.dec)
    z0, z1 = np.fft.rfft(r0), np.fft.rfft(r1)
    decrease = np.clip(np.abs(z0) ** 2 - np.abs(z1) ** 2, 0.0, None)
    motion = np.abs(np.fft.rfft(v)) ** 2
    if not (decrease.sum() > 0 and motion.sum() > 0):
        return dict(NO_LINE)
    k = int(np.argmax(decrease))
    band = np.abs(f - f[k]) <= max(TONE_HALF_WIDTH * f[k], 2.0 * (f[1] - f[0]))
    off0, off1 = (np.fft.irfft(np.where(band, 0.0, z), r0.size)[rows] for z in (z0, z1))
    t_off, p_off, _ = paired_chunk_test(off0, off1, chunk)
    return {"line_hz": float(f[k]), "share": float(decrease[band].sum() / decrease.sum()), "motion": float(motion[band].sum() / motion.sum()),
            "t_off": float(t_off), "p_off": float(p_off)}


def _a_single_tone(split: Split, before: LinearModel, after: LinearModel, chunk: int, level: float, ev: dict[str, Any]) -> str | None:
    """Why a delay ``after`` adds to ``before`` is a tone, or ``None``.  A delay shifts every force
    the drive commands, so its gain spreads over the frequencies where that force changes (the
    motion's, and the friction's switches); a gain held by one narrow line that the motion hardly
    has, and not confirmed (at the round's ``level``) on the rest of the spectrum, is a force
    oscillating in time (a ripple, a disturbance) that a shift of phase fits at that one
    frequency.  A real delay can also put most of its gain in one line, the oscillation it
    causes in the closed loop (a chatter where the motion hardly moves), but it also predicts
    the force better everywhere else."""
    tone = single_tone(split, before, after, chunk)
    ev.update(gain_share_in_one_line=round(tone["share"], 3), line_hz=round(tone["line_hz"], 4), motion_share_in_the_line=round(tone["motion"], 4),
              t_heldout_outside_the_line=round(tone["t_off"], 2), p_heldout_outside_the_line=float(f"{tone['p_off']:.3g}"))
    if tone["share"] >= TONE_GAIN_SHARE and tone["motion"] < TONE_MOTION_SHARE and tone["p_off"] > level:
        return (f"{100 * tone['share']:.0f} % of its held-out gain lies within {100 * TONE_HALF_WIDTH:.0f} % of {tone['line_hz']:.3g} Hz, where the "
                f"motion has {100 * tone['motion']:.1f} % of its power, and without that line it gains nothing significant (t = {tone['t_off']:.2f}, "
                f"p = {tone['p_off']:.2g}): a force oscillating in time, which a delay fits at one frequency")
    return None


def _beyond_a_free_switch(m: LinearModel, null: LinearModel, split: Split, cfg: LoopConfig, chunk: int) -> tuple[HeldOut, bool]:
    """Held-out test of a delay candidate ``m`` against its ``null`` when both may time the
    switch of friction freely (:func:`_with_switch_timing`): the nested comparison leaves the
    delay only what it does to the rest of the force (the inertia's timing), which is what a
    real delay carries and a late filtered switch does not.  Also returns whether the switch was
    refuted on the held-out run (:func:`_switch_refuted`), when the test is the plain one."""
    null_sw = _fit(_with_switch_timing(null.copy(), split, cfg), split)
    if _switch_refuted(null, null_sw, split, cfg, chunk):
        return heldout(split, null, m, chunk, effect="input_delay"), True
    m_sw = _fit(_with_switch_timing(m.copy(), split, cfg), split)
    return heldout(split, null_sw, m_sw, chunk, effect="input_delay"), False


def _switch_refuted(null: LinearModel, null_sw: LinearModel, split: Split, cfg: LoopConfig, chunk: int) -> bool:
    """Whether the freely timed switch that ``null_sw`` adds to ``null`` (both fitted) predicts the
    held-out run significantly worse than ``null`` without it (at ``alpha``, by the minimum gain).
    Its timing is chosen on the estimation run; a timing that held only there (stops of a
    trapezoid, where a sticking contact's switch lags by the stop) is no rival explanation of the
    held-out run, and comparing a delay against it compares two models that both fail there (a
    rig built elsewhere, a delay of 1.6 samples on a sweep: 2.5 % held-out error without the
    switch, 5.6 % with it)."""
    if not any(t.name == "switch_timing" for t in null_sw.terms):
        return False
    h = heldout(split, null_sw, null, chunk)
    return h.p <= cfg.alpha and h.gain >= cfg.min_gain


def _beats_a_free_switch(h_sw: HeldOut, h: HeldOut, level: float, cfg: LoopConfig, share_may_relax: bool = True) -> bool:
    """Whether a delay's held-out gain beyond a freely timed switch of friction (``h_sw``) stands,
    given its gain on all moving rows (``h``, already shown at the family-wise ``level``): at
    ``level``, or at the nominal ``alpha`` when it keeps :data:`DELAY_SWITCH_SHARE` of that gain
    (``share_may_relax``: not for a delay the rows clear of reversals confirm only at ``alpha``).
    The comparison asks whether the gain is the switch's, not whether there is one; a delay that
    explains far more than the switch can hold it in the few chunks where the two differ."""
    if h_sw.gain < cfg.min_gain:
        return False
    return h_sw.p <= level or (share_may_relax and h_sw.p <= cfg.alpha and h_sw.gain >= DELAY_SWITCH_SHARE * h.gain)


def _with_switch_timing(m: LinearModel, split: Split, cfg: LoopConfig) -> LinearModel:
    """``m`` (unfitted) plus ``sign(qd)`` with a coefficient of its own, advanced by the shift of
    :data:`DELAY_STEPS` beyond ``m``'s timing that cross-validates best on the estimation rows,
    or ``m`` itself when no shift lowers its cross-validated error."""
    best_cv, best = _cv(m, split, cfg), m
    for steps in DELAY_STEPS:
        cand = m.copy()
        cand.terms.append(switch_timing(float(steps)))
        try:
            cv = _cv(cand, split, cfg)
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            continue
        if cv < best_cv:
            best_cv, best = cv, cand
    return best


def _combine(a: LinearModel, b: LinearModel, b_name: str, dt: float) -> LinearModel:
    """Variant ``a`` with effect ``b_name`` of variant ``b`` added (both extend the same model)."""
    if b_name == "input_delay":
        out = _with_delay(a, b.delay, dt)
    else:
        out = a.copy()
        out.terms = out.terms + [t for t in b.terms if t.name == b_name]
    out.effects = out.effects + [b_name]
    return out


def _pair_step(st: _State, cfg: LoopConfig, rnd: int, cands: list[tuple[float, Effect, LinearModel]], far: ClearRows,
               fnd: dict[str, Finding], prog: Progress) -> bool:
    """When no single effect passes, two may enter together: effects that are confounded (a
    position-dependent friction and force, a drift and a Stribeck curve) can each fail alone, the
    one absorbing part of the other's force the wrong way, even raising the cross-validated error
    of the estimation run alone (a friction asymmetry beside a position-dependent force).  Any two
    candidates are fitted jointly, and a pair whose joint fit lowers that error by
    ``min_estimation_gain`` is tried: the grid parameters of both chosen again together
    (each was chosen alone, given a model without the other) before any held-out test (an outside
    audit's drift beside a position-dependent friction, on a run that lingers in one place late:
    chosen alone, the pair predicts the held-out run 17 % worse than the current model, chosen
    together 87 % better); it enters when *each* of the two passes the held-out
    test given the other, with the minimum gain (so that a real effect cannot carry a false one in),
    at the level of the next round split over the pairs that pass the estimation-only checks
    (a physical fit of both, a lower BIC, a plausible baseline; a pair left out early for gaining
    too little on held-out data counts too), and the pair together passes the BIC and the
    plausibility of the baseline.  Returns whether a pair entered."""
    dt = st.split.est.dt
    pool = [(eff, m) for _, eff, m in cands]
    pairs = [(pool[i], pool[j]) for i in range(len(pool)) for j in range(i + 1, len(pool))]
    if not pairs:
        return False
    creep = _creeping(st) if any(eff.creeping for eff, _ in pool) else st
    fitted: list[tuple[Effect, Effect, _State, LinearModel, float, dict[str, Any]]] = []
    shared = 0  # the pairs that could enter, whatever the held-out tests show
    current_cv: dict[tuple[bool, bool], float] = {}  # the current model's, per state (creeping or not) and scoring
    for (ea, ma), (eb, mb) in pairs:
        prog.update(note=f"round {rnd}: {ea.name} + {eb.name}")
        ps = creep if ea.creeping or eb.creeping else st
        split = ps.split
        try:
            both = _fit(_combine(ma, mb, eb.name, dt), split)
            if any(e.check(both, split.est) is not None for e in (ea, eb)):
                continue
            by_travel = has_position_basis(both, ps.model)
            key = (ps is creep, by_travel)
            if key not in current_cv:
                current_cv[key] = _cv(ps.model, split, cfg, by_travel)
            if not cfg.gains_on_estimation(sse_gain(_cv(both, split, cfg, by_travel), current_cv[key])):
                continue  # it cannot enter: no share of the level
            # each member was chosen alone, partly absorbing the other: both are chosen again
            # together before any held-out test, which would otherwise judge the two wrong choices
            both = _fit(_rechoose(both, [ea.name, eb.name], ps, cfg), split)
            if any(e.check(both, split.est) is not None for e in (ea, eb)):
                continue
            if heldout(split, ps.model, both, st.chunk).gain < cfg.min_gain:
                shared += 1  # left out by a held-out test, so it keeps its share of the level
                continue
        except (IdentificationError, np.linalg.LinAlgError, ValueError):
            continue
        dbic = _delta_bic(both, ps.model, split)
        change, implausible = _plausibility(st.base_phys, st.base_std, both, st.moving_split, cfg,
                                            not (ea.even_in_speed and eb.even_in_speed), _level_reference(st))
        if dbic >= 0 or implausible is not None:
            continue
        shared += 1
        fitted.append((ea, eb, ps, both, dbic, change))
    level = cfg.level(rnd + 1, shared)
    best: tuple[float, list[Step], LinearModel] | None = None
    for ea, eb, ps, both, dbic, change in fitted:
        split = ps.split
        h = heldout(split, ps.model, both, st.chunk)
        if h.gain < cfg.min_gain or (best is not None and h.ranking_gain <= best[0]):
            continue
        marginals: dict[str, dict[str, Any]] = {}
        passed = True
        for eff, other in ((ea, eb), (eb, ea)):
            reduced = _fit(_tested_against(both, eff.name, ps), split)
            hm = heldout(split, reduced, both, st.chunk, effect=eff.name)
            ok = hm.p <= level and hm.t >= cfg.t_threshold and hm.gain >= cfg.min_gain
            mg: dict[str, Any] = {"given": other.name, "t_heldout": round(hm.t, 2), "p_heldout": float(f"{hm.p:.3g}"), "validation_gain": round(hm.gain, 5)}
            far_level = eff.level_clear_of_reversals(both, level, cfg.alpha)
            if far_level is not None:
                hf = heldout_clear(split, reduced, both, st.chunk, far, eff.refit_clear_of_reversals)
                ok = ok and hf is not None and hf.p <= far_level and (not eff.whole_motion or eff.consistency_only
                                                                     or (hf.t >= cfg.t_threshold and hf.gain >= cfg.min_gain))
                mg["t_heldout_away_from_reversals"] = round(hf.t, 2) if hf is not None else None
                mg["validation_gain_away_from_reversals"] = round(hf.gain, 5) if hf is not None else None
            if ok and eff.name == "input_delay":
                hs, refuted = _beyond_a_free_switch(both, reduced, split, cfg, st.chunk)
                ok = _beats_a_free_switch(hs, hm, level, cfg) and _a_single_tone(split, reduced, both, st.chunk, level, mg) is None
                mg["t_heldout_beyond_a_free_switch"] = round(hs.t, 2)
                if refuted:
                    mg["free_switch_refuted_on_held_out_data"] = True
            marginals[eff.name] = mg
            if not ok:
                passed = False
                break
        if not passed:
            continue
        e_est, e_val = split.errors(both)
        steps = []
        for eff, other in ((ea, eb), (eb, ea)):
            ev: dict[str, Any] = {}
            f = fnd.get(eff.evidence)
            if f is not None:
                ev["residual_test"] = f.as_dict()
            ev.update(entered_with=other.name, validation_gain=round(h.gain, 5), t_heldout=round(h.t, 2), p_heldout=float(f"{h.p:.3g}"),
                      given_other=marginals[eff.name], level=float(f"{level:.3g}"), level_shared_by=shared, delta_bic=round(float(dbic), 1), baseline_parameters=change,
                      moving_rows_error_pct={"estimation": round(split.errors_moving(both)[0], 4), "validation": round(h.error_after, 4)})
            mg = marginals[eff.name]
            reason = (f"entered together with {other.name} (neither passes alone): held-out error {h.error_before:.3f} -> {h.error_after:.3f} % "
                      f"on moving rows{' within the estimation travel' if h.within_travel else ''}; given {other.name} t = {mg['t_heldout']:.1f}, p = {mg['p_heldout']:.2g} <= {level:.2g}; BIC {dbic:+.1f}")
            steps.append(Step(rnd, eff.name, True, reason, ev, e_est, e_val, both.params(), both))
        best = (h.ranking_gain, steps, both)
    if best is None:
        return False
    _, steps, both = best
    st.steps.extend(steps)
    st.model = both
    st.err = st.split.errors(both)
    _describe_rows(st)
    _joint_refit(st, cfg, rnd)
    _backward(st, cfg, rnd, steps[1].effect)
    for s in steps:
        if s.effect in st.model.effects:
            s.parameters = st.model.params()
    return True


def stage_report(st: _State, cfg: LoopConfig, names: list[str]) -> LoopResult:
    """Stage 4: residual analysis of the final model, unexplained structure, the result."""
    split = st.moving_split
    S, rows = split.est, split.est_fit
    y_hat = st.model.predict(S)
    r = S.y - y_hat
    final_f = _analyse_rows(S, rows, r, y_hat, cfg.seed)
    st.findings["final_estimation"] = final_f
    unexplained = []
    for f in final_f:
        if f.significant:
            tried = [e for e in f.suggests if e in names]
            unexplained.append({"variable": f.variable, "run": "estimation", "z": round(f.z, 1), "statistic": round(f.statistic, 5),
                                "candidates_tried": tried, "note": "residual still depends on " + f.variable + "; no catalogue effect reduced the held-out error enough",
                                **{k: v for k, v in f.detail.items()}})
    if split.val is not split.est:
        V, vrows = split.val, split.val_test
        yv = st.model.predict(V)
        fv = _analyse_rows(V, vrows, V.y - yv, yv, cfg.seed)
        st.findings["final_validation"] = fv
        for f in fv:
            if f.significant:
                unexplained.append({"variable": f.variable, "run": "validation", "z": round(f.z, 1), "statistic": round(f.statistic, 5),
                                    "candidates_tried": [e for e in f.suggests if e in names], "note": "structure in the held-out run's residual", **{k: v for k, v in f.detail.items()}})
    res = LoopResult(split, st.base, st.base_err, st.steps, st.model, st.err, unexplained, st.findings, alignment=st.alignment)
    be, bv = split.errors_moving(st.base)
    fe, fv_ = split.errors_moving(st.model)
    rot = res.rotary
    res.standstill = {
        "rule": "rows slower than rest_fraction x the estimation run's 99th-percentile speed are standstill (set-valued stiction: "
                "a stuck axis holds any force up to break-away); they are left out of every fit and test",
        "rest_fraction": cfg.rest_fraction,
        "rest_speed": float(f"{S.rest_speed:.6g}"), "rest_speed_unit": "rad/s" if rot else "m/s",
        "estimation_rows_at_rest_pct": round(100.0 * float(1.0 - split.est_fit.sum() / max(split.est_rows.sum(), 1)), 2),
        "creep_fraction": cfg.creep_fraction,
        "creeping_rule": "rows slower than rest_speed but faster than creep_fraction x the same speed scale, where the measured position moves, "
                         "are creeping: left out too, except where pre-sliding is chosen, fitted and tested (with the model it is tested against)",
        "estimation_rows_creeping_pct": round(100.0 * float((split.est_creep.sum() - split.est_fit.sum()) / max(split.est_rows.sum(), 1)), 2),
        "creeping_rows_in_final_fit": st.split is st.creep_split,
        "validation_rows_at_rest_pct": round(100.0 * float(1.0 - split.val_test.sum() / max(split.val_rows.sum(), 1)), 2),
        "baseline_moving_rows_error_pct": {"estimation": round(be, 4), "validation": round(bv, 4)},
        "final_moving_rows_error_pct": {"estimation": round(fe, 4), "validation": round(fv_, 4)},
    }
    res.selection = {
        "rule": "forward selection; an effect enters when its held-out chunk test (Newey-West t) has p <= alpha / (2**round x effects tested, counting those that pass the estimation-only checks: cross-validated error gain >= min_estimation_gain, BIC, plausible baseline), "
                "its held-out gain >= min_gain, BIC decreases and the baseline parameters stay plausible (a delay or a resonance must also pass "
                "on the held-out rows clear of reversals and stops); the best held-out gain enters; "
                "then joint refit of every accepted effect's grid parameters and backward elimination (stay with p <= alpha); "
                "models with a position basis are tested on the held-out rows within the estimation travel when the held-out run goes beyond it; "
                "when no single effect passes, a pair of effects whose joint fit has a cross-validated error gain >= min_estimation_gain "
                "enters when each passes given the other (p <= alpha / (2**(round + 1) x pairs "
                "tried that pass the estimation-only checks), held-out gain >= min_gain) and the pair passes the BIC and plausibility tests; when no pair passes either, an accepted "
                "effect is replaced by another catalogue effect that passes the same tests in its place (p <= alpha / (2**(round + 2) x "
                "exchanges tried that pass them)) and beats the current model on held-out data and in cross-validated error",
        "alpha": cfg.alpha, "t_threshold": cfg.t_threshold, "min_gain": cfg.min_gain, "min_estimation_gain": cfg.min_estimation_gain,
        "max_parameter_ratio": cfg.max_parameter_ratio,
        "chunk_rows": st.chunk,
    }
    timing = dict(getattr(S.data, "timing", {}) or {})
    if split.val is not split.est:
        timing = {"estimation": timing, "validation": dict(getattr(split.val.data, "timing", {}) or {})}
    res.timing = timing
    res.detection_limits = detection_limits(S, rot)
    return res


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
        force rows; on the moving rows under ``standstill``), unexplained residual structure and
        the residual tests.
    """
    for name, run in (("est", est), ("val", val)):
        if not (isinstance(run, AxisData) or (name == "val" and run is None)):
            raise InvalidInputError(f"`{name}` must be an AxisData (see gmsfric.loop.load_axis_data), got {type(run).__name__}")
    cfg = config or LoopConfig()
    if not isinstance(cfg, LoopConfig):
        raise InvalidInputError(f"`config` must be a LoopConfig, got {type(cfg).__name__}")
    names = _check_names(cfg)
    split, chunk = stage_prepare(est, val, cfg)
    st = stage_baseline(split, chunk, cfg)
    stage_select(st, cfg, names)
    result = stage_report(st, cfg, names)
    emit(result, check_result(result))
    return result


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
