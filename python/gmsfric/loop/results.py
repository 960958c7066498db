"""Results of the identification loop: the tested steps, the outcome, its JSON and text table.

:class:`LoopResult` follows the shared result protocol (:mod:`gmsfric.results`).  Its JSON
fields are a contract: ``estimation``, ``validation``, ``baseline``, ``alignment``, ``steps``,
``final``, ``unexplained``, ``residual_tests``, ``closed_loop``; every parameter is
``{"value", "std", "stderr", "unit"}`` in SI (``stderr`` equals ``std``, the name the identify
wing uses; ``unit`` is the SI unit, rotary when the axis is).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import units as _units
from ..errors import InvalidInputError
from ..results import Result
from .idim import LinearModel
from .residuals import Finding

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..axis import AxisModel
    from ..system import ClosedLoopResult
    from .heldout import Split

# Quantity of every parameter the baseline and the effect catalogue produce (exact names, then
# name patterns); ``None`` marks a name without a known unit.
_PARAMETER_QUANTITIES = {
    "M": "mass", "m_load": "mass",
    "Fv": "damping", "dFv_asym": "damping", "dFv_drift": "damping",
    "Fc": "force", "offset": "force", "Fs_minus_Fc": "force", "dF_moving": "force", "dFc_asym": "force", "dFc_drift": "force",
    "vs": "velocity",
    "stribeck_delta": "dimensionless", "zeta": "dimensionless", "drift_tau_over_T": "dimensionless",
    "delay_s": "time", "sampling_hold_s": "time", "heating_tau_s": "time",
    "dFc_heating": "damping", "dFv_heating": "damping_per_velocity",
    "dFc_heating_trend": "damping", "dFv_heating_trend": "damping_per_velocity",
    "fn_hz": "frequency",
}
_PARAMETER_PATTERNS = (
    (re.compile(r"w_(block\d+|switch)$"), "force"),
    (re.compile(r"Delta_(block\d+|switch)$"), "position"),
    (re.compile(r"(dFc_q|Fq)_(P\d+|(sin|cos)\d+_.*)$"), "force"),
)


def parameter_quantity(name: str) -> str | None:
    """The quantity (see :mod:`gmsfric.units`) of a loop parameter, ``None`` if unknown."""
    if name in _PARAMETER_QUANTITIES:
        return _PARAMETER_QUANTITIES[name]
    for pattern, quantity in _PARAMETER_PATTERNS:
        if pattern.match(name):
            return quantity
    return None


def parameter_unit(name: str, rotary: bool = False) -> str | None:
    """The SI unit of a loop parameter (``"N s/m"``; rotary ``"N m s/rad"``), ``None`` if unknown."""
    q = parameter_quantity(name)
    return None if q is None else _units.si_unit(q, rotary)


def _num(x: float) -> float | None:
    return round(float(x), 4) if np.isfinite(x) else None


def _round_params(p: dict[str, dict[str, float]], rotary: bool = False) -> dict[str, dict[str, Any]]:
    def r(x: float) -> float | None:
        return None if not np.isfinite(x) else float(f"{x:.6g}")

    return {k: {"value": r(v["value"]), "std": r(v["std"]), "stderr": r(v["std"]), "unit": parameter_unit(k, rotary)} for k, v in p.items()}


@dataclass
class Step:
    """One tested effect.

    Attributes
    ----------
    round : int
        Loop round (1 = first effect tried on top of the baseline).
    effect : str
    accepted : bool
    reason : str
        Why it was accepted or rejected.
    evidence : dict
        The residual test pointing at this effect before the step (see :class:`Finding`),
        plus the cross-validation gain, held-out t statistic and BIC change.
    estimation_error_pct, validation_error_pct : float
        Errors of the model with this effect.
    parameters : dict
        ``{name: {"value", "std"}}`` of the extended model (SI).
    """

    round: int
    effect: str
    accepted: bool
    reason: str
    evidence: dict[str, Any]
    estimation_error_pct: float
    validation_error_pct: float
    parameters: dict[str, dict[str, float]]
    model: LinearModel | None = field(default=None, repr=False)

    def as_dict(self, rotary: bool = False) -> dict[str, Any]:
        return {
            "round": self.round,
            "effect": self.effect,
            "accepted": self.accepted,
            "reason": self.reason,
            "evidence": self.evidence,
            "estimation_error_pct": _num(self.estimation_error_pct),
            "validation_error_pct": _num(self.validation_error_pct),
            "parameters": _round_params(self.parameters, rotary),
        }


@dataclass
class LoopResult(Result):
    """Outcome of :func:`~gmsfric.loop.run_loop`: ``to_dict()`` (alias ``as_dict()``) is the
    JSON of ``gmsfric loop``, ``table()`` its text report, ``plot()`` its figures.

    ``closed_loop_runs`` holds the closed-loop simulations behind ``closed_loop`` (not in the
    JSON), keyed by ``(model, run)``.
    """

    kind = "loop"

    split: "Split"
    baseline: LinearModel
    baseline_errors: tuple[float, float]
    steps: list[Step]
    final: LinearModel
    final_errors: tuple[float, float]
    unexplained: list[dict[str, Any]]
    findings: dict[str, list[Finding]]
    closed_loop: dict[str, Any] = field(default_factory=dict)
    alignment: dict[str, Any] = field(default_factory=dict)
    closed_loop_runs: dict[tuple[str, str], "ClosedLoopResult"] = field(default_factory=dict, repr=False)
    standstill: dict[str, Any] = field(default_factory=dict)
    selection: dict[str, Any] = field(default_factory=dict)
    timing: dict[str, Any] = field(default_factory=dict)
    detection_limits: dict[str, Any] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    @property
    def effects(self) -> list[str]:
        """Accepted effects, in order."""
        return list(self.final.effects)

    @property
    def rotary(self) -> bool:
        """Whether the axis is rotary (positions in rad, forces in N m)."""
        return bool(getattr(self.split.est.data, "rotary", False))

    def _body(self) -> dict[str, Any]:
        rot = self.rotary
        return {
            "estimation": self.split.est.data.source,
            "validation": self.split.holdout,
            "baseline": {
                "model": self.baseline.describe(),
                "estimation_error_pct": round(self.baseline_errors[0], 4),
                "validation_error_pct": round(self.baseline_errors[1], 4),
                "parameters": _round_params(self.baseline.params(), rot),
            },
            "preprocessing": self.split.preprocessing,
            "alignment": self.alignment,
            "steps": [s.as_dict(rot) for s in self.steps],
            "final": {
                "effects": self.effects,
                "model": self.final.describe() + "".join(f" + {e}" for e in self.final.effects if e != "input_delay" and e not in self.final.describe()),
                "estimation_error_pct": round(self.final_errors[0], 4),
                "validation_error_pct": round(self.final_errors[1], 4),
                "parameters": _round_params(self.final.params(), rot),
            },
            "unexplained": self.unexplained,
            "residual_tests": {k: [f.as_dict() for f in v] for k, v in self.findings.items()},
            "closed_loop": self.closed_loop,
            "standstill": self.standstill,
            "selection": self.selection,
            "timing": self.timing,
            "detection_limits": self.detection_limits,
        }

    def axis_model(self) -> "AxisModel":
        """The final model as an :class:`~gmsfric.axis.AxisModel` (effects in feedback)."""
        from .axis_model import to_axis_model

        est = self.split.est
        return to_axis_model(self.final, est, gain=est.data.gain, kind="rotary" if self.rotary else "linear", provenance=self.provenance)

    def _extras(self) -> dict[str, Any]:
        # `load_model` on the loop's JSON gives the final model, ready to simulate.
        try:
            return {"gmsfric_model": self.axis_model().model_document()}
        except InvalidInputError as exc:  # a model the core cannot simulate (non-positive mass)
            return {"gmsfric_model_error": str(exc)}

    def as_dict(self) -> dict[str, Any]:
        """Alias of :meth:`to_dict`."""
        return self.to_dict()

    def table(self) -> str:
        """Before/after table: baseline, every tested effect, final model, unexplained structure."""
        return format_table(self)

    def plot(self) -> dict[str, "Figure"]:
        """Every figure of the run by file stem (see :func:`gmsfric.loop.plots.figures`)."""
        from .plots import figures

        return figures(self)


def _limits_line(lim: dict[str, Any], rotary: bool) -> str:
    """One line of what the estimation run can show: the smallest pre-sliding contact, delay and
    Stribeck speed, and the resonances, in display units."""
    def v(name: str, key: str) -> str:
        e = lim[name]
        return _units.format_value(e[key], e["quantity"], rotary, digits=3)

    return (f"this log resolves: position {v('position_resolution', 'value')}; pre-sliding blocks from "
            f"{v('presliding_hysteresis', 'smallest_break_displacement')}; delays from {v('input_delay', 'smallest_delay')} "
            f"(within a sample: alignment); Stribeck speeds from {v('stribeck', 'smallest_stribeck_speed')}; resonances "
            f"{v('compliance', 'lowest_resonance')} to {v('compliance', 'highest_resonance')}")


def format_table(result: "LoopResult") -> str:
    """Before/after table: baseline, every tested effect, final model, unexplained structure."""
    d = result._body()
    rot = result.rotary
    lines = [f"estimation: {d['estimation']}    validation: {d['validation']}"]
    pre = d.get("preprocessing") or {}
    if pre:
        lines.append(f"position filter: {pre['cutoff_hz']:.4g} Hz ({pre['chosen_by']})")
    lines.append("")
    lines.append(f"{'step':<36}{'est %':>8}{'val %':>8}  decision")
    b = d["baseline"]
    lines.append(f"baseline: {b['model']}")
    lines.append(f"{'baseline':<36}{b['estimation_error_pct']:>8.3f}{b['validation_error_pct']:>8.3f}")
    al = d.get("alignment") or {}
    for a in al.get("tests", []):
        lines.append(f"  {'alignment +' + format(a['shift_s'] * 1e3, '.3g') + ' ms, after r' + str(a['after_round']):<34}{a['estimation_error_pct']:>8.3f}{a['validation_error_pct']:>8.3f}  "
                     f"{'APPLIED (timing within a sample, not an effect)' if a['applied'] else 'not applied'} t = {a['t_heldout']}")
    ss = d.get("standstill") or {}
    if ss:
        fu = _units.display_unit("velocity", rot)
        v, shown = _units.to_display(ss["rest_speed"], "velocity", rot)
        lines.append(f"  standstill (|qd| < {float(v):.3g} {shown}) left out of fits and tests: {ss['estimation_rows_at_rest_pct']:.1f} % of estimation rows, "
                     f"{ss['validation_rows_at_rest_pct']:.1f} % of held-out rows")
        if ss.get("creeping_rows_in_final_fit"):
            lines.append(f"  of them, {ss['estimation_rows_creeping_pct']:.1f} % of estimation rows creep (the position moves): "
                         "fitted and tested with pre-sliding in the model")
        del fu
    tm = d.get("timing") or {}
    for run, t in (tm.items() if "estimation" in tm else [("estimation", tm)]):
        if t.get("repeated_stamps_merged"):
            lines.append(f"  {run} log: {t['repeated_stamps_merged']} repeated time stamps, the samples of each averaged into one")
        if t.get("resampled"):
            lines.append(f"  {run} log resampled onto a uniform {t['median_step_s'] * 1e3:.4g} ms grid (steps from {t['min_step_s'] * 1e3:.4g} to "
                         f"{t['max_step_s'] * 1e3:.4g} ms, {t['irregular_steps_pct']:.1f} % irregular)"
                         + (f"; position step as logged {_units.format_value(t['position_step_as_logged'], 'position', rot)}"
                            if "position_step_as_logged" in t else ""))
    lim = d.get("detection_limits") or {}
    if lim:
        lines.append("  " + _limits_line(lim, rot))
    for s in d["steps"]:
        e = "   n/a" if s["estimation_error_pct"] is None else f"{s['estimation_error_pct']:8.3f}"
        v = "   n/a" if s["validation_error_pct"] is None else f"{s['validation_error_pct']:8.3f}"
        mark = "ADDED " if s["accepted"] else "      "
        lines.append(f"  r{s['round']} {s['effect']:<31}{e:>8}{v:>8}  {mark}{s['reason']}")
    f = d["final"]
    lines.append("")
    lines.append(f"{'final: ' + (', '.join(f['effects']) or 'no effect added'):<36}{f['estimation_error_pct']:>8.3f}{f['validation_error_pct']:>8.3f}")
    lines.append(f"before -> after: estimation {b['estimation_error_pct']:.3f} -> {f['estimation_error_pct']:.3f} %, validation {b['validation_error_pct']:.3f} -> {f['validation_error_pct']:.3f} %")
    lines.append("final parameters (value ± 1 std, SI):")
    for k, p in f["parameters"].items():
        std = "" if p["std"] is None else f" ± {p['std']:.3g}"
        unit = "" if p["unit"] in (None, "1") else f" {p['unit']}"
        lines.append(f"  {k:<24}{p['value']:.6g}{std}{unit}")
    if d["unexplained"]:
        lines.append("unexplained residual structure:")
        for u in d["unexplained"]:
            lines.append(f"  {u['run']}: depends on {u['variable']} (z = {u['z']}), tried: {', '.join(u['candidates_tried']) or 'nothing applicable'}")
    else:
        lines.append("unexplained residual structure: none significant")
    if d.get("closed_loop"):
        lines.append("closed-loop simulation errors (%): position / velocity / acceleration / force")
        for m, runs in d["closed_loop"].items():
            for r, e in runs.items():
                lines.append(f"  {m:<9}{r:<28}{e['position_pct']:.4f} / {e['velocity_pct']:.3f} / {e['acceleration_pct']:.2f} / {e['force_pct']:.2f}")
    return "\n".join(lines)


__all__ = ["LoopResult", "Step", "format_table", "parameter_unit", "parameter_quantity"]
