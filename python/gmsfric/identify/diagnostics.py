"""Findings about a fit's reliability: collected while fitting, then warned (``FitWarning``) and
stored in the result's ``diagnostics`` list (``{"code", "parameter", "message"}`` in the JSON).

Every identifier runs the checks that apply to it; the shared ones live here: a parameter at or
near a bound, a standard error over 100 %, chi2/dof far from 1, a clipped (saturated) signal, an
input that depends on the past output (feedback) while an open-loop estimator is used.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ..errors import FitWarning

#: Codes of the findings (the ``code`` field of a diagnostic).
CODES = {
    "at_bound": "a parameter sits at (or within 0.1 % of) a bound of the fit",
    "ordering": "a non-physical ordering of the parameters (fs < fc, ...)",
    "degenerate": "a block or parameter the data do not determine (zero, merged, outside the data)",
    "chi2": "chi2/dof far from 1: the model or the noise level does not fit the data",
    "stderr": "a standard error above 100 % of its value (or not finite)",
    "coverage": "the data range does not cover a parameter",
    "saturation": "a signal is clipped at its extremes (drive or sensor saturation)",
    "closed_loop": "the input depends on the past output: closed-loop data fed to an open-loop estimator",
    "data": "few or rejected data (plateaus, bins, reversals)",
    "poor_fit": "the model explains little of the data (wrong signal, gain or unit?)",
    "units": "a scale implausible for a servo axis (sample rate, speed): a column in another unit than declared?",
    "delay_ambiguous": "another delay fits about as well (a periodic excitation's lines cannot tell delays a whole period apart)",
    "held_back": "an effect the data support, kept out because it would make the baseline's physics implausible",
    "unconfirmed": "an effect that passed the tests on all rows but that the rows where it should show on its own do not confirm (too small a gain there)",
}


@dataclass(frozen=True)
class Diagnostic:
    """One finding: ``code`` (see :data:`CODES`), the ``parameter`` it concerns (or ``None``) and
    a one-line ``message``."""

    code: str
    message: str
    parameter: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"code": self.code, "parameter": self.parameter, "message": self.message}


@dataclass
class Findings:
    """The findings of one fit, in the order they were made (one per code and parameter)."""

    items: list[Diagnostic] = field(default_factory=list)

    def add(self, code: str, message: str, parameter: str | None = None) -> None:
        if code not in CODES:  # pragma: no cover - a programming error
            raise ValueError(f"unknown diagnostic code {code!r}")
        if any(d.code == code and d.parameter == parameter for d in self.items):
            return
        self.items.append(Diagnostic(code, message, parameter))

    def __len__(self) -> int:
        return len(self.items)

    def has(self, code: str, parameter: str | None = None) -> bool:
        return any(d.code == code and (parameter is None or d.parameter == parameter) for d in self.items)


def emit(result: Any, findings: Findings, *, stacklevel: int = 3) -> None:
    """Store ``findings`` in ``result.diagnostics`` (as JSON-able dicts, after any already there)
    and warn each with :class:`~gmsfric.errors.FitWarning`."""
    result.diagnostics = list(result.diagnostics) + [d.to_dict() for d in findings.items]
    label = getattr(result, "model", None) or result.kind
    for d in findings.items:
        warnings.warn(f"{label}: {d.message}", FitWarning, stacklevel=stacklevel)


def format_block(diagnostics: list[Mapping[str, Any]]) -> str:
    """The short text block the CLI prints after the table (empty without findings)."""
    if not diagnostics:
        return ""
    lines = [f"diagnostics ({len(diagnostics)}):"]
    for d in diagnostics:
        lines.append(f"  ! {d.get('code', '?')}: {d.get('message', '')}")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- shared checks


def check_bounds(findings: Findings, name: str, value: float, lower: float | None, upper: float | None, *, log: bool = False,
                 what: str = "", rel: float = 1e-3) -> bool:
    """Flag ``value`` at (within ``rel`` of the bound's scale) its lower or upper bound; ``log``
    compares in logs (for parameters fitted as logarithms).  Returns whether it was flagged."""
    if not np.isfinite(value):
        findings.add("degenerate", f"{name} is not finite", name)
        return True
    for bound, side in ((lower, "lower"), (upper, "upper")):
        if bound is None or not np.isfinite(bound):
            continue
        if log:
            hit = bound > 0 and value > 0 and abs(np.log(value / bound)) <= rel
        else:
            scale = abs(bound) if bound != 0 else 0.0
            hit = abs(value - bound) <= rel * scale if scale > 0 else value == bound
        if hit:
            findings.add("at_bound", f"{name} = {value:.4g} is at its {side} bound {bound:.4g}{what}", name)
            return True
    return False


def check_stderr(findings: Findings, parameters: Mapping[str, tuple[float, float]], *, skip: set[str] | frozenset[str] = frozenset(),
                 limit: float = 1.0) -> None:
    """Flag parameters whose standard error exceeds ``limit`` times their magnitude (or is not
    finite).  Parameters at zero (``skip``, or exactly 0) are not judged relative to their value."""
    for name, (value, se) in parameters.items():
        if name in skip or value == 0:
            continue
        if not np.isfinite(se):
            findings.add("stderr", f"{name}: the data do not determine it (no finite standard error)", name)
        elif se > limit * abs(value):
            findings.add("stderr", f"{name}: standard error {se / abs(value):.0%} of the value", name)


def check_chi2(findings: Findings, chi2: float, dof: int, *, what: str = "", low: float | None = 0.5, high: float = 2.0,
               rescaled: bool = True) -> None:
    """Flag chi2/dof far from 1: significant (p < 1e-3 either side) and outside ``[low, high]``
    (``low=None``: only a large chi2, when the noise level was estimated from the residual or may
    be overestimated); ``rescaled``: whether the fit scales its standard errors by chi2/dof (the
    message says so)."""
    if dof < 1 or not np.isfinite(chi2):
        return
    ratio = chi2 / dof
    p_high = float(stats.chi2.sf(chi2, dof))
    p_low = float(stats.chi2.cdf(chi2, dof))
    if ratio > high and p_high < 1e-3:
        findings.add("chi2", f"chi2/dof = {ratio:.3g}{what}: the residual is larger than the noise the fit assumes "
                             "(wrong model, unmodelled effects or too small a noise estimate); "
                             + ("the standard errors are rescaled by it" if rescaled else "the estimates and their standard errors are not to be trusted"))
    elif low is not None and ratio < low and p_low < 1e-3:
        findings.add("chi2", f"chi2/dof = {ratio:.3g}{what}: the residual is smaller than the stated noise (noise overestimated)")


def check_saturation(findings: Findings, name: str, values: NDArray[np.float64], *, min_fraction: float = 0.002, min_run: int = 3) -> None:
    """Flag a signal that sits at its maximum or minimum for runs of consecutive samples (a
    clipped drive or sensor): a continuous signal reaches its extremes at isolated samples."""
    v = np.asarray(values, dtype=float)
    if v.size < 100 or np.ptp(v) == 0:
        return
    span = float(np.ptp(v))
    for extreme, side in ((float(v.max()), "maximum"), (float(v.min()), "minimum")):
        at = np.abs(v - extreme) <= 1e-9 * span
        if at.sum() < max(min_run, min_fraction * v.size):
            continue
        # runs of consecutive samples at the extreme
        edges = np.diff(np.concatenate(([0], at.astype(np.int8), [0])))
        runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
        if runs.max() >= min_run:
            findings.add("saturation", f"{name} is clipped at its {side} ({extreme:.4g}) on {at.mean():.1%} of the samples "
                                       "(saturated drive or sensor): the linear estimate is biased there", name)


def fraction_at_limit(u: NDArray[np.float64], lo: float = -np.inf, hi: float = np.inf) -> float:
    """Share of the samples of a drive command ``u`` at one of its finite limits ``lo``, ``hi``
    (a saturated drive; 0 without a finite limit or samples)."""
    u = np.asarray(u, dtype=float)
    finite = [limit for limit in (lo, hi) if np.isfinite(limit)]
    if u.size == 0 or not finite:
        return 0.0
    tol = 1e-9 * max(max(abs(limit) for limit in finite), 1.0)
    at = np.zeros(u.size, dtype=bool)
    if np.isfinite(lo):
        at |= u <= lo + tol
    if np.isfinite(hi):
        at |= u >= hi - tol
    return float(at.mean())


def feedback_strength(u: NDArray[np.float64], y: NDArray[np.float64], *, na: int = 4, nb: int = 10, nf: int = 5,
                      max_samples: int = 40000) -> tuple[float, float]:
    """How much the present and future input explain of the output beyond an ARX model on the
    past output and input (a sampled plant answers ``u[k]`` at ``y[k+1]`` at the earliest):
    returns the fractional reduction of the residual variance and its F-test p-value.

    Open-loop data: ~0 (the input does not know the output's noise).  In a feedback loop the
    controller's next outputs react to ``y[k]``, noise included, so they explain part of it: the
    same noise that biases an open-loop (H1) estimate of such data."""
    u = np.asarray(u, dtype=float)
    y = np.asarray(y, dtype=float)
    n = u.size
    lag = max(na, nb)
    k = np.arange(lag, n - nf)
    if k.size < 20 * (na + nb + nf):
        return 0.0, 1.0
    if k.size > max_samples:
        k = k[:: int(np.ceil(k.size / max_samples))]
    u = (u - u.mean()) / (np.std(u) or 1.0)
    y = (y - y.mean()) / (np.std(y) or 1.0)
    past = [y[k - j] for j in range(1, na + 1)] + [u[k - j] for j in range(1, nb + 1)]
    future = [u[k + j] for j in range(0, nf + 1)]
    target = y[k]

    def rss(cols: list[NDArray[np.float64]]) -> float:
        a = np.column_stack(cols + [np.ones(k.size)])
        coef, *_ = np.linalg.lstsq(a, target, rcond=None)
        r = target - a @ coef
        return float(r @ r)

    r0 = rss(past)
    r1 = rss(past + future)
    if r0 <= 1e-10 * float(target @ target):
        return 0.0, 1.0  # a noise-free output: nothing for feedback to bias
    dof = k.size - len(past) - len(future) - 1
    f = ((r0 - r1) / len(future)) / max(r1 / dof, 1e-300)
    return float(1.0 - r1 / r0), float(stats.f.sf(f, len(future), dof))


def check_feedback(findings: Findings, u: NDArray[np.float64], y: NDArray[np.float64], *, threshold: float = 0.03) -> None:
    """Flag an input that the past output predicts (feedback) when the open-loop estimator is used."""
    gain, p = feedback_strength(u, y)
    if gain > threshold and p < 1e-6:
        findings.add("closed_loop", f"the input reacts to the output (feedback: the next inputs explain {gain:.0%} of the output's "
                                    "noise): closed-loop data fed to the open-loop estimator are biased; give the external excitation (--excitation)")


__all__ = ["Diagnostic", "Findings", "CODES", "emit", "format_block", "check_bounds", "check_stderr", "check_chi2", "check_saturation",
           "fraction_at_limit", "check_feedback", "feedback_strength"]
