"""The effect catalogue: candidate extensions of the force model, each a set of regression
columns (linear parameters) with, for some, a nonlinear parameter fitted by a grid search.

=============================  ===============================================================
``asymmetric_friction``        viscous friction (and, without an offset in the model, the Coulomb
                               level) differ between the two directions
``stribeck``                   ``(Fs - Fc) sign(qd) exp(-|qd/vs|^delta)``: friction goes from its
                               level at rest ``Fs > 0`` to the sliding level (either way)
``presliding_hysteresis``      GMS / Maxwell-slip blocks: elasto-plastic elements of break
                               displacement ``Delta_i`` and break force ``w_i`` (rate-independent
                               hysteresis after each reversal), with a stiffest element at the
                               position resolution (``w_switch``) that is not evidence on its own
``position_dependent_friction``  ``sign(qd) g(q)``: the Coulomb level varies along the travel
``position_dependent_force``   ``g(q)``, independent of direction: cogging, springs, cables
``input_delay``                the force acts ``tau`` after it is commanded, ``tau`` beyond one
                               sample (timing within a sample is the loop's alignment, not an effect)
``friction_drift``             ``(Fc sign(qd) + Fv qd) h(t)``: friction changes over the run
``heating``                    ``(dFc sign(qd) + dFv qd) m(t)``, ``m`` the speed ``|qd|`` low-passed
                               with a time constant ``tau`` (s): friction that follows the recent
                               motion (lubricant or contact temperature)
``compliance``                 a load ``m2`` on a spring-damper (``fn``, ``zeta``) behind the
                               measured motor: ``m2 (H(s) - 1) qdd``
``offset``                     a constant force (when the model has none)
=============================  ===============================================================

``g(q)`` is either a Legendre polynomial over the estimation run's travel (smooth: springs,
gravity compensation, wear) or a Fourier series at periods picked from the residual's
periodogram in the position domain (cogging, screw pitch).  ``h(t)`` is linear or exponential
(warm-up) in time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from numpy.typing import NDArray
from scipy import fft, ndimage, optimize, signal

from .. import curves
from .. import models as _models
from ..axis import legendre_columns
from ..units import si_unit
from .idim import Array, LinearModel, Signals, Term, advance, decimation_settling_rows, term_rows

# ------------------------------------------------------------------------------------------
# column builders (full rate)


def _legendre(s: Signals, degree: int) -> Array:
    """Legendre columns over the estimation travel; beyond it the degree-1 column goes on and the
    curved ones hold their edge values (as the axis model's series do): a held-out run that
    leaves the travel meets a spring or a weight that goes on growing, not one frozen at the
    edge, and no bump of the fit extrapolated along its steep tangent."""
    lo, hi = s.q_range
    x = 2.0 * (s.q - lo) / max(hi - lo, 1e-12) - 1.0
    return legendre_columns(x, degree, linear=True)[:, 1:]


def _fourier(s: Signals, periods: tuple[float, ...], harmonics: int) -> Array:
    cols = []
    for p in periods:
        for h in range(1, harmonics + 1):
            w = 2 * np.pi * h / p
            cols += [np.sin(w * s.q), np.cos(w * s.q)]
    return np.column_stack(cols)


def _basis(s: Signals, h: tuple) -> Array:
    kind = h[0]
    if kind == 0:  # legendre degree
        return _legendre(s, int(h[1]))
    return _fourier(s, tuple(h[2:]), int(h[1]))


def _basis_names(prefix: str, h: tuple, rotary: bool = False) -> tuple[str, ...]:
    if h[0] == 0:
        return tuple(f"{prefix}_P{d}" for d in range(1, int(h[1]) + 1))
    names = []
    unit = "mrad" if rotary else "mm"  # the period, in thousandths of the position unit
    for p in h[2:]:
        for k in range(1, int(h[1]) + 1):
            names += [f"{prefix}_sin{k}_{p * 1e3:.4g}{unit}", f"{prefix}_cos{k}_{p * 1e3:.4g}{unit}"]
    return tuple(names)


def _play(s: Signals, delta: float) -> Array:
    """Maxwell-slip element of unit break force and break displacement ``delta`` (compiled core),
    driven by the measured position.

    Pre-sliding is displacement while the contact holds, so the element must only move when the
    axis does.  The zero-phase filtered position cannot be used: it leaks the motion after a stick
    into the stick, where the force crosses the stiction band with the axis at rest, and an
    element driven by it fits that ramp as "pre-sliding" on any axis that sticks at reversals."""
    def make() -> Array:
        m = _models.MaxwellSlip(k=[1.0 / delta], w=[1.0])
        return _models.simulate_friction(m, s.t + 0.0, np.asarray(s.data.position, dtype=float))

    return s.cached(("play", float(delta)), make)


def _compliance(s: Signals, fn: float, zeta: float) -> Array:
    w = 2 * np.pi * fn
    # (H - 1) qdd with H = (2 zeta w s + w^2) / (s^2 + 2 zeta w s + w^2): -s^2/(...) qdd
    b, a = signal.bilinear([-1.0, 0.0, 0.0], [1.0, 2 * zeta * w, w * w], fs=s.fs)
    # Start at rest relative to the first acceleration (the load follows it): a filter started
    # from zero rings for several 1/(zeta w) and that ringing is not in the data.
    return signal.lfilter(b, a, s.qdd, zi=signal.lfilter_zi(b, a) * s.qdd[0])[0]


def lowpassed_speed(s: Signals, tau: float) -> Array:
    """``m' = (|qd| - m) / tau`` from ``m(0) = |qd(0)|`` (the core's heating state), exact for a
    speed held over each sample."""
    a = float(np.exp(-s.dt / tau))
    x = np.abs(s.qd)
    return signal.lfilter([1.0 - a], [1.0, -a], x, zi=[a * x[0]])[0]


def _heating(s: Signals, tau: float) -> Array:
    m = lowpassed_speed(s, tau)
    return np.column_stack([np.sign(s.qd) * m, s.qd * m])


def heating_trend(term: Term) -> Term:
    """Heating's trend in time alone: a friction change that decays with the same time constant
    whatever the motion does (a drift, ``(dFc sign(qd) + dFv qd) exp(-t / tau)``).  Over a steady
    motion the low-passed speed is just that; heating is evidence of itself only where the
    friction follows the motion's changes of pace, so it is tested against the model with this
    trend."""
    return Term(term.name, ("dFc_heating_trend", "dFv_heating_trend"), lambda s, h: _heating_trend(s, h[0]), term.hyper, term.hyper_names)


def _heating_trend(s: Signals, tau: float) -> Array:
    h = np.exp(-s.t / tau)
    return np.column_stack([np.sign(s.qd) * h, s.qd * h])


def _drift(s: Signals, tau_frac: float, duration: float) -> Array:
    """Drift columns on run ``s`` over the time scale of the estimation run (``duration``, s): a
    warm-up's time constant and a trend's slope are properties of the axis in seconds, so a
    held-out run of another length meets the drift the axis model carries (which is saved in
    seconds), not one stretched to its own length."""
    T = max(duration, 1e-9)
    h = (s.t / T - 0.5) if tau_frac <= 0 else np.exp(-s.t / (tau_frac * T))
    return np.column_stack([np.sign(s.qd) * h, s.qd * h])


# ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Effect:
    """One catalogue entry.

    Attributes
    ----------
    name : str
        Catalogue name (e.g. ``"stribeck"``).
    description : str
        The physical effect in one line.
    evidence : str
        Residual test (see :mod:`gmsfric.loop.residuals`) that points at this effect.
    variants : callable
        ``variants(model, est_signals, residual_rows) -> list[LinearModel]``: the candidate
        extended models (unfitted), one per value of the effect's nonlinear parameters.
    refine : callable, optional
        ``refine(est_signals) -> [(low, high), ...]``: bounds of the nonlinear parameters when
        they are refined continuously from the best grid variant (a sharp resonance, a large
        Stribeck hump or a warm-up between two grid points fits poorly and extrapolates badly).
    whole_motion : bool
        The effect acts on the whole motion (a delay, a resonance), so its held-out gain must hold
        on the rows clear of reversals and stops too; what gains only there is the switch of
        friction seen through the velocity filter.
    probe : callable, optional
        ``probe(params, est_signals) -> bool``: whether a variant lies beyond the physical range of the
        nonlinear parameter on purpose (``physical`` refuses it).  Such variants are fitted too,
        and when one of them cross-validates best the effect is refused: the data prefer what the
        effect is not, and its nearest physical variant would only be a proxy.
    contested : callable, optional
        ``contested(params, est_signals) -> bool``: whether a variant that ``physical`` refuses is
        one the data may still single out: it stands when it cross-validates clearly better than
        every probe (its error at most ``select.CONTESTED_MARGIN`` times theirs), since the
        probes are what it would otherwise be taken for.
    clear_of_reversals : callable, optional
        ``clear_of_reversals(params) -> bool``: whether a fit that looks like what the filters make
        of a reversal (a Stribeck *dip*) must also gain on the rows clear of reversals and stops,
        at the nominal level ``alpha``: a consistency check of an effect already found on all
        rows, so not corrected for the family of tests.
    consistency_only : bool
        For a whole-motion effect: the rows clear of reversals and stops only have to agree with
        the gain found on all rows, at the nominal level ``alpha`` (one-sided, no floor on t),
        rather than confirm it at the family-wise level.  For a resonance: what excites it (a
        change of acceleration) mostly sits next to the stops of the usual moves, so the rows
        clear of them hold little of its gain, and a switch of friction, which gains only at
        reversals, still fails there.
    refit_clear_of_reversals : bool
        For a whole-motion effect: the test on the rows clear of reversals and stops fits both
        models again on the estimation rows clear of them.  Fitted on all moving rows, the
        baseline's mass and friction absorb what the filters make of the stops; a delay fitted
        with them gains on the rows clear of stops by undoing that bias (a clean rig with strong
        friction took a 1.8 ms "delay" that way), and gains nothing once both models are fitted
        where the filters have settled.
    creeping : bool
        The effect's evidence lies where the axis creeps: its variants are chosen, fitted and
        tested (cross-validated, held-out, BIC; forward, in pairs, in exchanges and backward) on
        the moving and creeping rows, the current model fitted there too.  Pre-sliding: an axis
        that crosses its contact's elastic range after a reversal does so slower than the
        standstill speed on many axes (an outside audit's rig: held-out t = 1.5 on the moving rows,
        146 with the creeping rows).  Terms that need the sign of the filtered velocity are not
        judged there: at such speeds it is noise.
    null : callable, optional
        ``null(term) -> Term``: the part of the effect's term that is no evidence for the effect
        on its own.  The effect's tests (held-out, cross-validated, BIC; forward, in pairs and
        backward) compare against the model with this part kept rather than with the whole term
        removed, so the effect must explain what its null does not.
    acting : callable, optional
        ``acting(model, signals) -> Array``: how much the effect acts on each decimated row of
        ``signals``, from the fitted ``model`` (a force, or a share of one).  For an effect that
        acts in some places only: its held-out tests (forward, in pairs, in exchanges and
        backward) are also made on the chunks where it acts at least as much as in its mean
        chunk (``heldout.ACTING_FRACTION``), the smaller p-value doubled
        (``heldout.paired_chunk_test``).  With the effect, the baseline is refitted and differs
        from the null's everywhere, and chunks where the effect does not act would weigh as much
        as those where it does: a drift's force where a warm-up has died out, a contact's
        between reversals, once its blocks have all slipped.  The chunks are chosen from the
        fitted model, not the measured force, so a useless effect still gains nothing on them on
        average.
    rivals : callable, optional
        ``rivals(model, chosen, est_signals, residual_rows) -> [(rival, what), ...]``: models of
        what the effect may be taken for, built around its ``chosen`` variant from the current
        ``model`` and its residual (NaN off the fitted rows), each with a phrase saying what it
        is.  When one cross-validates clearly better than the chosen variant
        (``select.RIVAL_MARGIN``), the effect is refused wherever that variant was chosen: unlike
        a probe, a rival is no value of the effect's own parameters (a force oscillating in time
        for a resonance).
    chosen_clear_of_reversals : bool
        When no valid variant is chosen on the moving estimation rows (a probe fits best), the
        choice (grid and refinement) is made again on the estimation rows clear of reversals and
        stops (:func:`settled_rows`); that variant is then fitted and tested on all rows as usual,
        and must be physical there too.  A resonance rings on there after the reversal that
        excites it, while what the filters make of the friction's switch at the reversal is
        absent: on all rows a heavily damped "resonance" of negative load mass at the top of the
        band (a lead, one of the probes) can fit that blur best and hide a real one (an outside
        audit's rig: cross-validated error 0.61 of the baseline's for the probe against 0.83 for
        the planted resonance on all rows, 0.13 for the planted one clear of reversals).  Chosen
        there first, a resonance on a slow random run with few clear rows was lost to a probe.
    even_in_speed : bool
        The effect's force is the same in both directions at the same speed (a viscous friction
        that differs between the directions, a constant force).  Projected on ``sign(qd)`` such a
        force reflects only how differently the run moves the two ways, and a baseline without it
        takes that share into its Coulomb level: when it enters and the level falls, the
        baseline gives back what it absorbed, and the plausibility guard does not hold the fall
        against it (its mass and viscous coefficient stay checked).
    """

    name: str
    description: str
    evidence: str
    variants: Callable[[LinearModel, Signals, Array], list[LinearModel]]
    physical: Callable[[dict[str, dict[str, float]], Signals], str | None] | None = None
    refine: Callable[[Signals], list[tuple[float, float]]] | None = None
    whole_motion: bool = False
    probe: Callable[[dict[str, dict[str, float]], Signals], bool] | None = None
    null: Callable[[Term], Term] | None = None
    clear_of_reversals: Callable[[dict[str, dict[str, float]]], bool] | None = None
    contested: Callable[[dict[str, dict[str, float]], Signals], bool] | None = None
    consistency_only: bool = False
    refit_clear_of_reversals: bool = False
    creeping: bool = False
    acting: Callable[[LinearModel, Signals], Array] | None = None
    chosen_clear_of_reversals: bool = False
    even_in_speed: bool = False
    rivals: Callable[[LinearModel, LinearModel, Signals, Array], list[tuple[LinearModel, str]]] | None = None

    def check(self, model: LinearModel, s: Signals) -> str | None:
        """Why the ``model`` fitted on the run ``s`` is not physical for this effect (``None`` when
        it is)."""
        return None if self.physical is None else self.physical(model.params(), s)

    def level_clear_of_reversals(self, model: LinearModel, level: float, alpha: float) -> float | None:
        """Level at which the fitted ``model``'s term must also gain on the held-out rows clear of
        reversals and stops: the family-wise ``level`` for a whole-motion effect (the nominal
        ``alpha`` when :attr:`consistency_only`), the nominal ``alpha`` for a fit
        :attr:`clear_of_reversals` flags, ``None`` (no such test) otherwise."""
        if self.whole_motion:
            return alpha if self.consistency_only else level
        if self.clear_of_reversals is not None and self.clear_of_reversals(model.params()):
            return alpha
        return None

    def applicable(self, model: LinearModel) -> bool:
        return self.name not in model.effects and not (self.name == "offset" and any(t.name == "offset" for t in model.terms))


def _add(model: LinearModel, term: Term, effect: str) -> LinearModel:
    m = model.copy()
    m.terms.append(term)
    m.effects.append(effect)
    return m


def _asymmetric(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    # A Coulomb asymmetry is a constant force wherever the axis moves: with standstill rows left
    # out of the fit it *is* an offset (the baseline's, or the ``offset`` effect), so only the
    # viscous asymmetry is a column of its own.
    t = Term("asymmetric_friction", ("dFv_asym",), lambda s, h: np.abs(s.qd))
    return [_add(model, t, "asymmetric_friction")]


def _rms_acceleration(s: Signals) -> float:
    """The run's typical acceleration (rms over its rows): what sets how far and how fast the axis
    gets within the velocity filter's blur through a reversal."""
    return float(np.sqrt(np.mean(s.rows["qdd"] ** 2)))


def velocity_resolution(s: Signals) -> float:
    """Smallest speed scale a velocity curve can be identified on: three times the standstill
    threshold, and the speed the axis gains within the velocity filter's time constant at its
    typical (rms) acceleration -- through a reversal the filtered velocity cannot separate speeds
    closer than that.  A narrower "Stribeck curve" only marks the rows next to a reversal or a
    stop, where the force crosses the stiction band, and fits that instead of a speed law."""
    return max(3.0 * s.rest_speed, _rms_acceleration(s) / (2.0 * np.pi * s.cutoff))


def dip_resolution(s: Signals) -> float:
    """Speed band blurred through a reversal: the speed the axis gains at its rms acceleration
    within one period of the velocity filter, and three times the standstill speed.  Through a
    reversal or a stick the zero-phase filter spreads the change of ``sign(qd)`` over about that
    window, and the force's switch, seen against the filtered velocity, looks exactly like
    friction that is lower at low speed: a low-speed *dip* of friction (``Fs < Fc``) must keep at
    least half its depth beyond this speed.  A hump (``Fs > Fc``) is the opposite of that blur, so
    it may be as narrow as :func:`velocity_resolution`."""
    return max(3.0 * s.rest_speed, _rms_acceleration(s) / s.cutoff)


#: Time, in periods of the velocity filter's cut-off, that its response to a reversal or a stop
#: takes to settle (on either side: the filter is zero-phase).
REVERSAL_SETTLING_PERIODS = 2.0


def settled_rows(s: Signals) -> NDArray[np.bool_]:
    """Rows farther from a reversal (a change of sign of the filtered velocity) or a standstill
    row than both filters take to settle: ``REVERSAL_SETTLING_PERIODS / cutoff`` in time for the
    velocity filter, and :func:`~gmsfric.loop.idim.decimation_settling_rows` rows for the
    decimation filter.

    Where the axis sticks, the force crosses the stiction band while the position holds, and the
    zero-phase filters spread that over the rows before and after it: there ``sign(qd)`` switches
    at the wrong instant, and shifting the force in time or a slow resonance can make up for it.
    A speed threshold alone does not remove those rows after a fast breakaway."""
    qd = s.rows["qd"]
    event = ~s.moving
    event[1:] |= np.sign(qd[1:]) != np.sign(qd[:-1])
    half = max(int(np.ceil(REVERSAL_SETTLING_PERIODS / s.cutoff / (s.dt * s.dec))), decimation_settling_rows(s.dec))
    return ~ndimage.maximum_filter1d(event.astype(np.uint8), 2 * half + 1).astype(bool)


#: Widths (times the run's top speed) of the probe curves that are a drag across the motion.
STRIBECK_PROBE_WIDTHS = (2.0, 4.0)

#: Widest Stribeck curve fitted, times the run's top speed (the grid's upper end).
STRIBECK_MAX_WIDTH = 0.5

#: Stribeck exponents ``delta`` of the grid; the best curve is refined between them.
STRIBECK_DELTAS = (1.0, 2.0)


def _stribeck(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out: list[LinearModel] = []
    lo, hi = velocity_resolution(s), STRIBECK_MAX_WIDTH * s.v_scale
    if not hi > lo:
        return out
    grid = [(float(vs), delta) for delta in STRIBECK_DELTAS for vs in np.geomspace(lo, hi, max(2, min(14, int(np.ceil(6 * np.log10(hi / lo))) + 1)))]
    # probes: curves whose transition lies beyond the fastest motion; across the run's speeds
    # (Fs - Fc) exp(-(v/vs)^2) is a level and a term in v|v|, i.e. a drag
    grid += [(f * s.v_scale, 2.0) for f in STRIBECK_PROBE_WIDTHS]
    for vs, delta in grid:
        t = Term("stribeck", ("Fs_minus_Fc",), lambda s, h: np.sign(s.qd) * curves.stribeck_shape(s.qd, h[0], h[1]), (vs, delta), ("vs", "stribeck_delta"))
        out.append(_add(model, t, "stribeck"))
    return out


def _stribeck_dip(p: dict[str, dict[str, float]]) -> bool:
    """A *dip* (friction lower at low speed than sliding, ``Fs < Fc``) is what the switch of
    friction at a reversal looks like through the velocity filter and the decimation filter, and
    low speeds are mostly reversals: a dip must also gain on the rows clear of them, where that
    blur is absent (a hump, the opposite of the blur, is not checked there)."""
    return "Fs_minus_Fc" in p and p["Fs_minus_Fc"]["value"] < 0


def stribeck_bounds(s: Signals) -> list[tuple[float, float]]:
    """Bounds of ``(vs, delta)`` when the best grid curve is refined: the grid's range of widths.
    Between the grid's widths (a factor 1.4 apart) a large hump fits far worse than at its own
    width, and worse than the smooth drag probes, which have no width to miss: so it is refined
    before it meets them.  The refinement only fills in between the grid's points; whether a
    curve wider than the motion (a drag) fits better is the probes' question, as before."""
    return [(velocity_resolution(s), STRIBECK_MAX_WIDTH * s.v_scale), (min(STRIBECK_DELTAS), max(STRIBECK_DELTAS))]


#: Largest pre-sliding break displacement, as a fraction of the travel: pre-sliding is the elastic
#: range of a contact (micrometres on machine axes); a "break displacement" of a sizeable part of
#: the travel would be a force of the position since the last reversal, not friction.
PRESLIDING_MAX_FRACTION = 0.01


def presliding_range(s: Signals) -> tuple[float, float]:
    """Break displacements tried for pre-sliding blocks: from two steps of the measured position
    that drives them (its contact resolution, the encoder step) to the elastic range's upper
    bound.  Not bounded by the velocity filter's blur: the blocks follow the raw position, and
    what a narrow block shares with a switch of friction at the reversal is taken out by testing
    against that switch."""
    return 2.0 * s.contact_resolution, PRESLIDING_MAX_FRACTION * float(np.ptp(s.q))


def _presliding(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out: list[LinearModel] = []
    lo, hi = presliding_range(s)
    if not hi > lo:
        return out
    for dmax in np.geomspace(lo, hi, max(2, min(12, int(np.ceil(4 * np.log10(hi / lo))) + 1))):
        grid = tuple(float(d) for d in (dmax, dmax / 5.0, dmax / 25.0) if d >= lo)
        # one, two and three blocks: break forces are positive, and a set of blocks that only
        # fits with a negative one is refused, while a subset of them may be the contact
        for n in range(1, len(grid) + 1):
            t = Term("presliding_hysteresis", ("w_switch",) + tuple(f"w_block{i + 1}" for i in range(n)),
                     lambda s, h: np.column_stack([_play(s, d) for d in h]),
                     (float(s.contact_resolution),) + grid[:n], ("Delta_switch",) + tuple(f"Delta_block{i + 1}" for i in range(n)))
            out.append(_add(model, t, "presliding_hysteresis"))
    return out


def elastic_force(model: LinearModel, s: Signals) -> Array:
    """What the fitted ``model``'s pre-sliding blocks hold short of their break forces, on the
    decimated rows of ``s``: ``sum |w_k| (1 - |z_k|)`` over the blocks (the switch left out), with
    ``z_k`` each element's state as a share of its break force.  Zero once every block has
    slipped: a contact acts within its elastic range after each reversal, not between them."""
    term = next((t for t in model.terms if t.name == "presliding_hysteresis"), None)
    if term is None:
        return np.zeros(s.n_rows)
    theta = dict(zip(model.param_names, model.theta))
    w = np.abs([theta[n] for n in term.param_names[1:]])
    z = term_rows(term, s, model.delay / s.dt)[:, 1:]
    return (1.0 - np.clip(np.abs(z), 0.0, 1.0)) @ w


def reversal_switch(term: Term) -> Term:
    """The pre-sliding term's stiffest element alone: a block one encoder step wide,
    i.e. friction that switches where the measured position reverses.  Every contact does that
    (a Karnopp or LuGre contact as much as a Maxwell-slip one), and where the velocity filter
    blurs reversals it fits better than ``sign(qd)`` of the filtered velocity; that is no
    evidence of an elastic range, so pre-sliding is tested against the model with this switch."""
    return Term(term.name, term.param_names[:1], term.build, term.hyper[:1], term.hyper_names[:1])


def position_periods(s: Signals, r: Array, odd: bool, n_peaks: int = 2) -> list[float]:
    """Periods (m) of the strongest peaks of the residual's periodogram in the position domain.

    The residual (times ``sign(qd)`` when ``odd``) is averaged on a uniform position grid and
    Fourier transformed; peaks are ranked by power against the median level.
    """
    grid, prof = position_profile(s, r, odd)
    if prof is None:
        return []
    freqs, power = position_periodogram(grid, prof)
    if freqs.size < 4:
        return []
    span = grid[-1] - grid[0]
    # at least 1.5 periods over the travel: a longer "period" is a smooth trend (Legendre)
    ok = freqs > 1.5 / span
    power = np.where(ok, power, 0.0)
    idx, _ = signal.find_peaks(np.concatenate(([0.0], power, [0.0])))
    idx = idx - 1
    idx = idx[np.argsort(power[idx])[::-1]][:n_peaks]
    return [_refine_period(grid, prof, float(freqs[i]), float(freqs[1] - freqs[0])) for i in idx if power[i] > 0]


def _refine_period(grid: Array, prof: Array, f0: float, df: float) -> float:
    """The period near ``1/f0`` that a sine fits best: the periodogram's frequencies are spaced
    by one over the travel, so a peak is only known to within that spacing."""
    X0 = np.ones_like(grid)
    best_f, best = f0, -1.0
    for f in np.linspace(max(f0 - df, 0.5 * f0), f0 + df, 41):
        X = np.column_stack([X0, np.sin(2 * np.pi * f * grid), np.cos(2 * np.pi * f * grid)])
        c, *_ = np.linalg.lstsq(X, prof, rcond=None)
        explained = float(np.sum((X[:, 1:] @ c[1:]) ** 2))
        if explained > best:
            best_f, best = f, explained
    return float(1.0 / best_f)


def position_profile(s: Signals, r: Array, odd: bool, n_grid: int | None = None) -> tuple[Array, Array | None]:
    """Residual (or residual times ``sign(qd)``) averaged in uniform position bins."""
    q, qd = s.rows["q"], s.rows["qd"]
    moving = (np.abs(qd) > 0.05 * s.v_scale) & np.isfinite(r)
    if moving.sum() < 50:
        return np.zeros(0), None
    x = r * np.sign(qd) if odd else r
    lo, hi = np.percentile(q[moving], [0.5, 99.5])
    n_grid = n_grid or int(np.clip(moving.sum() // 8, 32, 1024))
    edges = np.linspace(lo, hi, n_grid + 1)
    i = np.clip(np.searchsorted(edges, q[moving]) - 1, 0, n_grid - 1)
    cnt = np.bincount(i, minlength=n_grid)
    tot = np.bincount(i, weights=x[moving], minlength=n_grid)
    prof = np.where(cnt > 0, tot / np.maximum(cnt, 1), np.nan)
    centres = 0.5 * (edges[1:] + edges[:-1])
    good = np.isfinite(prof)
    if good.sum() < 16:
        return centres, None
    prof = np.interp(centres, centres[good], prof[good])
    return centres, prof - prof.mean()


def position_periodogram(grid: Array, prof: Array) -> tuple[Array, Array]:
    """Spatial frequencies (1/m) and periodogram of a position profile (DC removed, Hann window)."""
    dq = grid[1] - grid[0]
    win = np.hanning(prof.size)
    spec = np.abs(np.fft.rfft((prof - prof.mean()) * win)) ** 2
    freqs = np.fft.rfftfreq(prof.size, dq)
    return freqs[1:], spec[1:]


def _position_term(name: str, prefix: str, h: tuple, odd: bool, rotary: bool) -> Term:
    """A position basis (:func:`_basis` with hyper-parameters ``h``) as a term: a friction level
    that changes along the travel (times ``sign(qd)``) when ``odd``, a force of the position
    otherwise."""
    if odd:
        return Term(name, _basis_names(prefix, h, rotary), lambda s, h: np.sign(s.qd)[:, None] * _basis(s, h), h, ())
    return Term(name, _basis_names(prefix, h, rotary), lambda s, h: _basis(s, h), h, ())


def fitted_period(model: LinearModel, s: Signals, r: Array, period: float, odd: bool) -> float:
    """The period near ``period`` (from :func:`position_periods`) at which one sine and cosine of
    the position, added to ``model``, fit the rows where ``r`` is defined best (least squares,
    the model's own coefficients fitted with them), within half a periodogram bin either way and
    no longer than the travel unless ``period`` already is (a sine of a longer period is a trend
    along the travel, which the Legendre basis fits; on a real EMPS run the fit stretched a
    period of one travel to one and a half).
    The periodogram is taken of the current model's residual, from which that model has already
    taken what its terms share with the sine (an offset its mean over the travel, a Coulomb level
    its odd part): a period read off it is biased, by 2-4 % on a rotary joint's gravity over 2.6
    turns (an outside audit), and the slightly wrong sine leaves a residual along the travel that
    another effect then absorbs."""
    rows = np.isfinite(r)
    span = float(np.ptp(s.q))
    # the periodogram's refinement returns at most two travels; anything else is left as given
    if rows.sum() < 20 or not span > 0 or not 0.0 < period <= 2.0 * span:
        return period
    Xb, y, steps = model.X(s)[rows], s.y[rows], model.delay / s.dt

    def sse(p: float) -> float:
        sine = _position_term("period", "sine", (1, 1, p), odd, False)
        X = np.hstack([Xb, term_rows(sine, s, steps)[rows]])
        c, *_ = np.linalg.lstsq(X, y, rcond=None)
        return float(np.sum((y - X @ c) ** 2))

    half = 0.5 * period**2 / span  # half the periodogram's spacing (1 / travel), as a period
    longest = max(period, min(period + half, span))
    res = optimize.minimize_scalar(sse, bounds=(max(period - half, 0.5 * period), longest), method="bounded",
                                   options={"xatol": 1e-4 * period})
    # a refinement that fits no better than the period it started from is no refinement
    return float(res.x) if res.success and res.fun < sse(period) else period


def _position_variants(model: LinearModel, s: Signals, r: Array, odd: bool, name: str) -> list[LinearModel]:
    prefix = "dFc_q" if odd else "Fq"
    hypers: list[tuple] = [(0, d) for d in (1, 2, 3, 4, 6, 8)]
    periods = [fitted_period(model, s, r, p, odd) for p in position_periods(s, r, odd)]
    for p in periods:
        for nh in (1, 2, 3):
            hypers.append((1, nh, p))
    if len(periods) > 1:
        hypers.append((1, 2, *periods))
    out = []
    rotary = bool(getattr(s.data, "rotary", False))
    for h in hypers:
        out.append(_add(model, _position_term(name, prefix, h, odd, rotary), name))
    return out


def _pos_friction(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    return _position_variants(model, s, r, True, "position_dependent_friction")


def _pos_force(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    return _position_variants(model, s, r, False, "position_dependent_force")


#: Delays (in samples) tried for ``input_delay``: beyond one sample, the loop's timing alignment
#: covers the sampling hold and the time stamp's uncertainty within a sample.
DELAY_STEPS = np.concatenate((np.arange(1.2, 2.0, 0.2), np.arange(2.0, 4.0, 0.25), np.arange(4.0, 12.0, 1.0), np.arange(12.0, 31.0, 3.0)))


def switch_timing(steps: float) -> Term:
    """``sign(qd)`` advanced ``steps`` samples beyond the model's timing, with its own coefficient:
    the switch of friction at a time of its own.  A contact that sticks at each reversal (a
    Karnopp contact) makes ``sign`` of the filtered velocity switch at another time than the
    friction does, on every rig and by the same lag; a delay of the whole force would absorb that
    lag (a clean rig on random moves: 0.6 ms, 22 % of held-out error), so a delay must keep its
    held-out gain when both its model and its null have this column at their best shifts."""
    return Term("switch_timing", ("Fc_switch",), lambda s, h: advance(np.sign(s.qd)[:, None], h[0]), (float(steps),), ("switch_shift_steps",))


def _delay(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out = []
    for steps in DELAY_STEPS:
        m = model.copy()
        m.delay = float(steps * s.dt)
        m.effects.append("input_delay")
        out.append(m)
    return out


#: Warm-up time constants tried, as fractions of the estimation run's duration (0: a linear
#: trend); the best warm-up is then refined between them (:data:`DRIFT_TAU_RANGE`).
DRIFT_TAUS = (0.0, 0.05, 0.15, 0.4, 1.0)
DRIFT_TAU_RANGE = (min(DRIFT_TAUS[1:]), max(DRIFT_TAUS))


def _drift_variants(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out = []
    duration = s.duration  # the estimation run's: the variants are built on it
    for tau in DRIFT_TAUS:
        t = Term("friction_drift", ("dFc_drift", "dFv_drift"), lambda s, h: _drift(s, h[0], duration), (tau,), ("drift_tau_over_T",))
        out.append(_add(model, t, "friction_drift"))
    return out


#: Time constants of ``heating``, in seconds: thermal, never faster than a second (a faster
#: "memory" of the speed is a velocity-dependent friction), and shorter than the run.  Memories up
#: to twice the run are tried as probes: over a memory as long as the run the low-passed speed only
#: grows with the distance travelled, a trend that a drift in time fits as well.
HEATING_MIN_TAU_S = 1.0


#: Shorter "memories" tried as probes (refused as heating): when one of them fits best, the
#: friction follows the current speed, a velocity curve (a drag growing with the speed, say).
HEATING_PROBE_TAUS_S = (0.1, 0.3)


def _heating_variants(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out: list[LinearModel] = []
    hi = max(2.0 * s.duration, 2.0 * HEATING_MIN_TAU_S)
    for tau in (*HEATING_PROBE_TAUS_S, *np.geomspace(HEATING_MIN_TAU_S, hi, 7)):
        t = Term("heating", ("dFc_heating", "dFv_heating"), lambda s, h: _heating(s, h[0]), (float(tau),), ("heating_tau_s",))
        out.append(_add(model, t, "heating"))
    return out


#: Damping ratios of a resonance between motor and load.  Above the largest, the response rises
#: less than 6 dB above the mass line (|H| = sqrt(1 + 4 zeta^2) / (2 zeta) < 2 at the natural
#: frequency) and a "load on a spring" is an added mass behind a low-pass filter, which fits any
#: smooth lag.  Below the smallest, no transmission is damped so little: the column rings on at
#: ``fn`` long after the acceleration that excites it, which is what a force oscillating at one
#: frequency whatever the motion does (a ripple, a tone) fits best.
COMPLIANCE_MIN_ZETA = 0.01
COMPLIANCE_MAX_ZETA = 0.3

#: Ratios tried as probes (refused as compliance): when one of them fits best, the data prefer a
#: lag (overdamped) or a persistent tone (undamped) to a resonance.
COMPLIANCE_PROBE_ZETAS = (0.002, 0.5, 0.7, 1.0)


#: Damping ratios of the physical grid of ``compliance``.
COMPLIANCE_GRID_ZETAS = (0.03, 0.1, 0.2)

#: Lowest resonance tried, Hz.
COMPLIANCE_MIN_HZ = 2.0


def compliance_frequencies(f_hi: float, zeta: float) -> Array:
    """Resonance frequencies tried at damping ratio ``zeta``: a geometric grid from
    :data:`COMPLIANCE_MIN_HZ` to ``f_hi`` with steps of ``zeta`` (relative, at least 3 %, at most
    20 %), so that a resonance lies within half its bandwidth (``2 zeta fn``) of a grid point.  A
    sharp resonance between two coarser grid points fits barely better than none (an outside
    audit's rig, zeta 0.034: 4 % of the error off the grid point 5 % away, 32 % at the planted
    frequency), and the refinement starts from the best grid point."""
    step = float(np.clip(zeta, 0.03, 0.2))
    n = int(np.ceil(np.log(f_hi / COMPLIANCE_MIN_HZ) / np.log1p(step))) + 1
    return np.geomspace(COMPLIANCE_MIN_HZ, f_hi, max(n, 2))


def _compliance_variants(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    out: list[LinearModel] = []
    f_hi = resonance_limit(s)
    if not f_hi > COMPLIANCE_MIN_HZ:
        return out
    for zeta in (*COMPLIANCE_GRID_ZETAS, *COMPLIANCE_PROBE_ZETAS):
        for fn in compliance_frequencies(f_hi, zeta):
            t = Term("compliance", ("m_load",), lambda s, h: _compliance(s, h[0], h[1]), (float(fn), zeta), ("fn_hz", "zeta"))
            out.append(_add(model, t, "compliance"))
    return out


def resonance_limit(s: Signals) -> float:
    """Highest resonance the rows resolve: below their Nyquist frequency and below the cut-off of
    the zero-phase filter, which removes what lies above it from the force and the motion alike
    (a "resonance" fitted there fits the filter's transition band: whatever sharp events, such
    as sticking, leave in it)."""
    return min(0.4 * s.fs / s.dec, s.cutoff)


#: Band searched for a force oscillating in time, relative to a resonance's frequency.
TONE_SEARCH_BAND = 0.15


def _tone_in_time(s: Signals, f_hz: float) -> Array:
    return np.column_stack([np.sin(2 * np.pi * f_hz * s.t), np.cos(2 * np.pi * f_hz * s.t)])


def tone_rivals(model: LinearModel, chosen: LinearModel, s: Signals, r: Array) -> list[tuple[LinearModel, str]]:
    """A force oscillating in time near the chosen resonance's frequency, whatever the motion
    does (a force ripple, a tone of the drive), as rivals of ``compliance``: the current
    ``model`` plus ``sin`` and ``cos`` of ``2 pi f t``.  The controller answers such a force, so
    the motion carries it at ``f``, and a lightly damped "resonance" there, which amplifies the
    acceleration at ``f``, predicts it on held-out data too.  A real resonance rings after what
    excites it, with the phase of each excitation, which no single tone follows over a run.
    ``f`` is the peak of the residual's periodogram (the rows left out set to zero, zero-padded
    to a grid of an eighth of the run's frequency resolution) within :data:`TONE_SEARCH_BAND` of
    the resonance, and its neighbours on that grid (a tone must keep its phase over the run).

    Parameters
    ----------
    model : LinearModel
        The current model, without ``compliance``.
    chosen : LinearModel
        ``model`` with the chosen ``compliance`` variant (its ``fn_hz`` sets the band searched).
    s : Signals
        The estimation run.
    r : ndarray
        The current model's residual on the rows of ``s`` (NaN on the rows left out of the fit).

    Returns
    -------
    list of (LinearModel, str)
        The rivals (unfitted) and what each is, for the refusal's message; empty when fewer than
        ten rows are fitted or the band holds no frequency of the grid.
    """
    fn = next(t.hyper[0] for t in chosen.terms if t.name == "compliance")
    rows = np.isfinite(r)
    if rows.sum() < 10:
        return []
    y = np.where(rows, r - float(np.mean(r[rows])), 0.0)
    n_fft = fft.next_fast_len(8 * y.size, real=True)
    power = np.abs(fft.rfft(y, n_fft))
    freqs = fft.rfftfreq(n_fft, s.dt * s.dec)
    band = np.flatnonzero((freqs >= fn * (1 - TONE_SEARCH_BAND)) & (freqs <= fn * (1 + TONE_SEARCH_BAND)))
    if band.size == 0:
        return []
    peak = band[int(np.argmax(power[band]))]
    out = []
    for f in freqs[max(peak - 2, 1) : peak + 3]:
        m = model.copy()
        m.terms = m.terms + [Term("tone", ("tone_sin", "tone_cos"), lambda s, h: _tone_in_time(s, h[0]), (float(f),), ("tone_hz",))]
        out.append((m, f"a force oscillating in time at {f:.4g} Hz whatever the motion does (a ripple, a tone)"))
    return out


def _offset(model: LinearModel, s: Signals, r: Array) -> list[LinearModel]:
    return [_add(model, Term("offset", ("offset",), lambda s, h: np.ones_like(s.q)), "offset")]


def _stribeck_ok(p: dict[str, dict[str, float]], s: Signals) -> str | None:
    if (why := _stribeck_curve_ok(p, s)) is not None:
        return why
    if _hump_never_falls(p, s):
        return (f"the friction never falls below its level at rest (by {stribeck_fall(p, s.v_scale):.3g}, less than {HUMP_MIN_FALL:g} x "
                f"(Fs - Fc) = {p['Fs_minus_Fc']['value']:.3g}) within the run's speeds: the viscous slope outweighs the hump, a convex "
                "velocity curve (drag) fits about the same")
    return None


def _stribeck_curve_ok(p: dict[str, dict[str, float]], s: Signals) -> str | None:
    # The curve may fall or rise towards rest (friction lower at low speed happens, e.g. in a
    # preloaded screw); what must hold is a positive friction level at rest, Fs = Fc + (Fs - Fc),
    # and a dip must be wider than the blur of the filtered velocity through a reversal.
    fc = p.get("Fc", {"value": 0.0})["value"]
    ds = p["Fs_minus_Fc"]["value"] if "Fs_minus_Fc" in p else 0.0
    if "vs" in p and p["vs"]["value"] > s.v_scale:
        return (f"the transition speed vs = {p['vs']['value']:.3g} lies beyond the run's speeds ({s.v_scale:.3g}): across the motion "
                "that curve is a force growing with the square of the speed (drag), not friction falling from rest")
    if fc + ds <= 0:
        return f"friction level at rest Fs = Fc + (Fs - Fc) = {fc + ds:.3g} is not positive"
    if ds > 0 and "Fc" in p and fc <= 0:
        return f"the sliding friction level Fc = {fc:.3g} is not positive: the hump carries all of the friction"
    if ds < 0 and "vs" in p:
        blur = DIP_BLUR_MARGIN * dip_resolution(s)
        if curves.stribeck_shape(blur, p["vs"]["value"], p.get("stribeck_delta", {"value": 1.0})["value"]) < 0.5:
            return (f"a dip (Fs - Fc = {ds:.3g}) of width vs = {p['vs']['value']:.3g} keeps less than half its depth beyond the velocity "
                    f"filter's blur through a reversal ({blur:.3g}): the switch of sign(qd) looks like that")
    return None


#: How many times :func:`dip_resolution` a dip must keep half its depth beyond.  That band is
#: estimated from the run's rms acceleration, and an axis often reverses faster: on the rigs of
#: both outside campaigns, which plant no dip, every dip named (seven false effects) was 1.05-1.18
#: times as wide as the narrowest the band allowed, while the real EMPS axis's own dip is 1.6-3.8
#: times as wide.
DIP_BLUR_MARGIN = 1.5


def _hump_never_falls(p: dict[str, dict[str, float]], s: Signals) -> bool:
    """A hump that the viscous slope outweighs: friction that only bends upward out of rest."""
    ds = p["Fs_minus_Fc"]["value"] if "Fs_minus_Fc" in p else 0.0
    return ds > 0 and "vs" in p and stribeck_fall(p, s.v_scale) < HUMP_MIN_FALL * ds


def _contested_hump(p: dict[str, dict[str, float]], s: Signals) -> bool:
    """A physical Stribeck curve but for a hump that never falls.  A drag bends upward too; such a
    hump is named only when it fits clearly better than the drag probes (:attr:`Effect.contested`),
    i.e. when its bend sits at low speed."""
    return _stribeck_curve_ok(p, s) is None and _hump_never_falls(p, s)


#: Smallest fall of the friction below its level at rest, as a fraction of ``Fs - Fc``, for a hump
#: to be a Stribeck curve.
HUMP_MIN_FALL = 0.1


def stribeck_fall(p: dict[str, dict[str, float]], v_max: float) -> float:
    """How far the sliding friction ``(Fs - Fc) exp(-|v/vs|^delta) + Fv' v`` falls below its level
    at rest for speeds up to ``v_max``, in the direction with the smaller viscous slope ``Fv'``.

    What makes a Stribeck curve is friction that *decreases* with speed out of rest (the cause of
    stick-slip).  A "hump" that the viscous slope outweighs everywhere is a friction curve that
    only bends upward: that is also what a drag growing with the square of the speed looks like,
    and the data cannot tell the two apart."""
    def value(name: str) -> float:
        return float(p[name]["value"]) if name in p else 0.0

    slope = value("Fv") - abs(value("dFv_asym"))
    v = np.linspace(0.0, max(v_max, 0.0), 512)
    curve = value("Fs_minus_Fc") * curves.stribeck_shape(v, p["vs"]["value"], p.get("stribeck_delta", {"value": 1.0})["value"]) + slope * v
    return float(curve[0] - curve.min())


def _heating_ok(p: dict[str, dict[str, float]], s: Signals) -> str | None:
    tau = p["heating_tau_s"]["value"] if "heating_tau_s" in p else HEATING_MIN_TAU_S
    if tau < HEATING_MIN_TAU_S:
        return (f"a memory of {tau:.2g} s is shorter than a thermal one ({HEATING_MIN_TAU_S:g} s): the friction follows the current "
                "speed, a velocity curve (e.g. a drag), not heating")
    if tau >= s.duration:
        return (f"a memory of {tau:.3g} s is as long as the run ({s.duration:.3g} s): the low-passed speed only grows with the "
                "distance travelled, a trend over the run that a drift in time fits as well, not heating")
    return None


def _load_ok(p: dict[str, dict[str, float]], s: Signals) -> str | None:
    m2 = p["m_load"]["value"] if "m_load" in p else 0.0
    mass = p["M"]["value"] if "M" in p else np.inf
    if not 0 < m2 < mass:
        return f"load mass m_load = {m2:.3g} is not between 0 and the axis mass M = {mass:.3g}"
    zeta = p["zeta"]["value"] if "zeta" in p else 0.0
    if zeta > COMPLIANCE_MAX_ZETA:
        return f"a damping ratio of {zeta:.2g} leaves no resonant peak: a lag, not a resonance"
    if zeta < COMPLIANCE_MIN_ZETA:
        return (f"a damping ratio of {zeta:.2g} rings on long after the motion that excites it: a force oscillating at one "
                "frequency (a ripple, a tone), not a load on a spring")
    return None


def _blocks_ok(p: dict[str, dict[str, float]], s: Signals) -> str | None:
    """A block's break force is the force its element holds: a negative one is no contact, however
    uncertain (two or three neighbouring blocks are correlated, and a set that cancels one against
    another fits the filters' blur at reversals, not an elastic range).  The grid's fewer-block
    variants remain for a contact that needs fewer.  The switch, part of the null, only must not
    be significantly negative (it may give way to a block at the resolution)."""
    for n, v in p.items():
        if n.startswith("w_block") and v["value"] < 0.0:
            return f"negative block break force {n} = {v['value']:.3g}"
        if n.startswith("w_switch") and v["value"] < -2 * v["std"]:
            return f"negative switch break force {n} = {v['value']:.3g}"
    return None


def detection_limits(s: Signals, rotary: bool = False) -> dict[str, dict[str, float | str]]:
    """What the run ``s`` can show of each effect whose grid its sampling or resolution bounds:
    the range of the nonlinear parameter the loop tries, in SI (``unit``: m or rad, m/s or
    rad/s, s, Hz).
    Outside it an effect is not looked for, or is something else: a delay within a sample is
    the timing alignment, a pre-sliding contact narrower than the resolution switches where the
    measured position reverses (the null pre-sliding is tested against), a Stribeck curve
    narrower than the velocity resolution only marks the rows next to reversals."""
    lo, hi = presliding_range(s)
    v_lo, v_hi = velocity_resolution(s), STRIBECK_MAX_WIDTH * s.v_scale
    f_hi = resonance_limit(s)
    # ``looked_for`` false: the range is empty, the run cannot show the effect at all
    limits: dict[str, dict[str, float | str]] = {
        "position_resolution": {"value": float(s.resolution), "quantity": "position",
                                "how": "the encoder step (1st percentile of the sample-to-sample changes) or the position noise, whichever is larger"},
        "presliding_hysteresis": {"smallest_break_displacement": float(lo), "largest_break_displacement": float(hi), "quantity": "position",
                                  "switch_width": float(s.contact_resolution), "looked_for": bool(hi > lo),
                                  "below": "a contact that narrow switches within the resolution: the switch of friction at the reversal"},
        "input_delay": {"smallest_delay": float(DELAY_STEPS[0] * s.dt), "largest_delay": float(DELAY_STEPS[-1] * s.dt), "quantity": "time",
                        "below": "timing within a sample is the alignment (reported under alignment), not an effect"},
        "stribeck": {"smallest_stribeck_speed": float(v_lo), "largest_stribeck_speed": float(v_hi), "quantity": "velocity", "looked_for": bool(v_hi > v_lo),
                     "below": "a narrower curve only marks the rows next to reversals and stops"},
        "compliance": {"lowest_resonance": float(COMPLIANCE_MIN_HZ), "highest_resonance": float(max(f_hi, COMPLIANCE_MIN_HZ)), "quantity": "frequency",
                       "looked_for": bool(f_hi > COMPLIANCE_MIN_HZ),
                       "above": "beyond the position filter's cut-off or the rows' Nyquist frequency the filter has removed it"},
        "friction_drift": {"shortest_warm_up": float(DRIFT_TAU_RANGE[0] * s.duration), "longest_warm_up": float(DRIFT_TAU_RANGE[1] * s.duration),
                           "quantity": "time", "below": "a faster change is a transient the run cannot tell from its start"},
    }
    for entry in limits.values():
        entry["unit"] = si_unit(str(entry["quantity"]), rotary)
    return limits


CATALOGUE: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect("asymmetric_friction", "friction differs between the two directions of motion", "velocity", _asymmetric, even_in_speed=True),
        Effect("stribeck", "friction changes from its level at rest to its sliding level at low speed (Stribeck curve)", "velocity", _stribeck, _stribeck_ok,
               probe=lambda p, s: p["vs"]["value"] > s.v_scale, clear_of_reversals=_stribeck_dip, contested=_contested_hump,
               refine=stribeck_bounds),
        Effect("presliding_hysteresis", "elasto-plastic pre-sliding after reversals (GMS / Maxwell-slip blocks)", "reversal", _presliding, _blocks_ok,
               null=reversal_switch, creeping=True, acting=elastic_force),
        Effect("position_dependent_friction", "the friction level varies along the travel", "position_odd", _pos_friction),
        Effect("position_dependent_force", "a force that depends on position only (cogging, spring, cable, gravity)", "position", _pos_force),
        Effect("input_delay", "the drive force acts a delay after it is commanded", "lag", _delay, whole_motion=True, refit_clear_of_reversals=True),
        Effect("friction_drift", "friction changes over the run (warm-up, lubricant)", "time", _drift_variants, acting=lambda m, s: m.term_force(s, ("friction_drift",)),
               refine=lambda s: [DRIFT_TAU_RANGE]),
        Effect("heating", "friction follows the recent motion (speed low-passed over seconds: temperature, lubricant)", "time", _heating_variants, _heating_ok,
               probe=lambda p, s: not HEATING_MIN_TAU_S <= p["heating_tau_s"]["value"] < s.duration, null=heating_trend),
        Effect("compliance", "a resonance between motor and load (flexible transmission)", "frequency", _compliance_variants, _load_ok,
               refine=lambda s: [(1.0, resonance_limit(s)), (min(COMPLIANCE_PROBE_ZETAS), max(COMPLIANCE_PROBE_ZETAS))], whole_motion=True,
               probe=lambda p, s: not COMPLIANCE_MIN_ZETA <= p["zeta"]["value"] <= COMPLIANCE_MAX_ZETA, consistency_only=True,
               chosen_clear_of_reversals=True, rivals=tone_rivals),
        Effect("offset", "a constant force (drive offset, gravity)", "mean", _offset, even_in_speed=True),
    )
}


#: Catalogue effects that are two forms of one phenomenon: friction that changes over the run,
#: following the clock (a drift) or the motion's recent pace (heating).  Over an estimation run of
#: steady pace their columns are nearly collinear, so the run that tells them apart is the held-out
#: one, with another pace; once one of them is in the model, the other replaces it when it predicts
#: that run better (``select._exchange_step``).
ALTERNATIVE_FORMS = (frozenset({"friction_drift", "heating"}),)


def alternative_forms(a: str, b: str) -> bool:
    """Whether effects ``a`` and ``b`` are two forms of one phenomenon (:data:`ALTERNATIVE_FORMS`)."""
    return frozenset({a, b}) in ALTERNATIVE_FORMS


#: Effects whose columns are functions of the position: a basis in the position is known only
#: over the travel the estimation run covered.
POSITION_EFFECTS = frozenset({"position_dependent_friction", "position_dependent_force"})


def has_position_basis(*models: LinearModel) -> bool:
    """Whether any of ``models`` has a term in the position (:data:`POSITION_EFFECTS`)."""
    return any(t.name in POSITION_EFFECTS for m in models for t in m.terms)
