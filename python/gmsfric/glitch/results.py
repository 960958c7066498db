"""Results of the glitch studies (the shared result protocol of :mod:`gmsfric.results`).

:class:`ScenarioResult` (the Fig. 14 sinusoid), :class:`CircleResult` (XY circle test),
:class:`CompensationResult` (friction compensation) and :class:`GlitchStudy`, the three together
as ``gmsfric glitch`` reports them.  Their JSON fields (``summary()``) are a contract.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np
from numpy.typing import NDArray

from ..results import Result
from ..system import ClosedLoopResult
from .metrics import GlitchReport

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class ScenarioResult(Result):
    """Runs of one scenario keyed by model name, with their glitch metrics (JSON: :meth:`summary`).

    Attributes
    ----------
    runs : dict of str -> ClosedLoopResult
    baselines : dict of str -> ndarray
        Frictionless error of the plant each run used (the linear error).
    metrics : dict of str -> GlitchReport
    """

    runs: Mapping[str, ClosedLoopResult]
    baselines: Mapping[str, NDArray[np.float64]]
    metrics: Mapping[str, GlitchReport]
    params: Mapping[str, object] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    kind = "glitch.sinusoid"

    def summary(self) -> dict[str, dict[str, object]]:
        """``{model: {"peak_error_m" (glitch height), "raw_peak_error_m", "duration_s", "area_m_s", "reversals"}}``."""
        return {k: r.to_dict() for k, r in self.metrics.items()}

    def _body(self) -> dict[str, Any]:
        return self.summary()

    def table(self) -> str:
        """Peak glitch per model."""
        return "\n".join(f"{k:>16}: peak glitch {m.height * 1e6:8.3f} µm, raw peak error {m.raw_peak_error * 1e6:8.3f} µm, "
                         f"duration {m.duration:.3g} s" for k, m in self.metrics.items())

    def plot(self) -> dict[str, "Figure"]:
        from .plots import plot_tracking_errors

        return {"glitch_tracking_errors": plot_tracking_errors(self)}


@dataclass(frozen=True)
class CircleResult(Result):
    """Circle runs keyed by model (``"none"``, ``"static"``, ``"gms"`` and, unless disabled,
    ``"static_stiction"``).

    Attributes
    ----------
    t, theta : ndarray
        Time (s) and reference angle (rad).
    radius : float
        Circle radius (m).
    x, y : dict of str -> ClosedLoopResult
        Per-axis runs.
    radial_error : dict of str -> ndarray
        ``sqrt(x^2 + y^2) - R`` (m).
    quadrant_glitch : dict of str -> dict of int -> float
        Per model, the glitch height (m) at 0, 90, 180, 270 deg against the frictionless radial
        error (signed: negative = the path dips inside the circle).
    """

    t: NDArray[np.float64]
    theta: NDArray[np.float64]
    radius: float
    x: Mapping[str, ClosedLoopResult]
    y: Mapping[str, ClosedLoopResult]
    radial_error: Mapping[str, NDArray[np.float64]]
    quadrant_glitch: Mapping[str, Mapping[int, float]]
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    kind = "glitch.circle"

    def summary(self) -> dict[str, object]:
        """JSON-able ``{"radius_m", model: {"radial_error_min_m", "radial_error_max_m",
        "peak_glitch_m", "quadrant_glitch_m": {"0": ..., "90": ..., ...}}}``."""
        out: dict[str, object] = {"radius_m": self.radius}
        sel = (self.theta >= 0) & (self.theta <= 2 * np.pi)
        for m, er in self.radial_error.items():
            q = self.quadrant_glitch[m]
            out[m] = {
                "radial_error_min_m": float(er[sel].min()),
                "radial_error_max_m": float(er[sel].max()),
                "peak_glitch_m": float(max(abs(v) for v in q.values())),
                "quadrant_glitch_m": {str(k): float(v) for k, v in q.items()},
            }
        return out

    def _body(self) -> dict[str, Any]:
        return self.summary()

    def table(self) -> str:
        """Glitch per quadrant and model."""
        lines = [f"{'model':>16}  " + "  ".join(f"{q:>7} deg" for q in sorted(next(iter(self.quadrant_glitch.values()), {})))]
        for m, q in self.quadrant_glitch.items():
            lines.append(f"{m:>16}  " + "  ".join(f"{v * 1e6:8.3f} µm" for _, v in sorted(q.items())))
        return "\n".join(lines)

    def plot(self) -> dict[str, "Figure"]:
        from .plots import plot_circle_polar

        return {"glitch_circle_polar": plot_circle_polar(self)}


@dataclass(frozen=True)
class CompensationResult(Result):
    """Runs of the true (GMS) axis with each compensation strategy.

    Attributes
    ----------
    runs : dict of str -> ClosedLoopResult
    feedforward : dict of str -> ndarray or None
    baseline : ndarray
        Frictionless error of the same loop.
    metrics : dict of str -> GlitchReport
    force_gain : float
        The plant's force per drive unit (N/V).
    """

    runs: Mapping[str, ClosedLoopResult]
    feedforward: Mapping[str, NDArray[np.float64] | None]
    baseline: NDArray[np.float64]
    metrics: Mapping[str, GlitchReport]
    force_gain: float = 1.0
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    kind = "glitch.compensation"

    def reduction(self, strategy: str) -> float:
        """Cut of the peak glitch height by ``strategy`` relative to no compensation (%)."""
        h0 = self.metrics["none"].height
        return float("nan") if h0 == 0 else 100.0 * (1.0 - self.metrics[strategy].height / h0)

    def summary(self) -> dict[str, dict[str, Any]]:
        """``{strategy: {"peak_error_m", "raw_peak_error_m", ..., "reduction_percent"}}``."""
        out: dict[str, dict[str, Any]] = {}
        for k, m in self.metrics.items():
            d = m.to_dict()
            d["reduction_percent"] = 0.0 if k == "none" else self.reduction(k)
            out[k] = d
        return out

    def _body(self) -> dict[str, Any]:
        return self.summary()

    def table(self) -> str:
        """Peak glitch per strategy and its reduction."""
        return "\n".join(f"{k:>28}: peak glitch {m.height * 1e6:8.3f} µm ({0.0 if k == 'none' else self.reduction(k):5.1f} % cut)"
                         for k, m in self.metrics.items())

    def plot(self) -> dict[str, "Figure"]:
        from .plots import plot_compensation

        return {"glitch_compensation": plot_compensation(self)}


def _angle_keys(doc: Any) -> Any:
    """``doc`` with the length suffixes of its keys turned into angle ones (``_m`` -> ``_rad``,
    ``_m_s`` -> ``_rad_s``): a rotary axis' glitches are angles, never lengths."""
    if isinstance(doc, Mapping):
        out = {}
        for k, v in doc.items():
            key = str(k)
            if key.endswith("_m"):
                key = key[:-2] + "_rad"
            elif key.endswith("_m_s"):
                key = key[:-4] + "_rad_s"
            out[key] = _angle_keys(v)
        return out
    if isinstance(doc, list):
        return [_angle_keys(v) for v in doc]
    return doc


@dataclass
class GlitchStudy(Result):
    """The sinusoid, circle and compensation studies of one ``gmsfric glitch`` run, with the
    settings they used (``parameters``).  ``parameters["axis"] == "rotary"``: the studies ran a
    rotary axis, so every length of the JSON is an angle (``*_rad`` fields instead of ``*_m``) and
    the table is in µrad.  ``saturation``: the share of samples each run spent at the drive limit."""

    sinusoid: ScenarioResult
    circle: CircleResult
    compensation: CompensationResult
    parameters: dict[str, Any]
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)
    saturation: dict[str, Any] | None = field(default=None, repr=False)

    kind = "glitch"

    @property
    def rotary(self) -> bool:
        """Whether the studies ran a rotary axis (lengths are angles)."""
        return self.parameters.get("axis") == "rotary"

    def _body(self) -> dict[str, Any]:
        studies = {"sinusoid": self.sinusoid.summary(), "circle": self.circle.summary(), "compensation": self.compensation.summary()}
        body: dict[str, Any] = {**(_angle_keys(studies) if self.rotary else studies), "parameters": self.parameters}
        if self.saturation is not None:
            body["saturation"] = self.saturation
        return body

    def table(self) -> str:
        """One line: the peak glitch of each model and of each compensation."""
        s = {k: m.height for k, m in self.sinusoid.metrics.items()}
        c = self.compensation
        h = {k: m.height for k, m in c.metrics.items()}
        unit = "µrad" if self.rotary else "µm"
        return (
            f"sinusoid peak glitch [{unit}]: " + ", ".join(f"{k} {v * 1e6:.3f}" for k, v in s.items())
            + f"; compensation: none {h['none'] * 1e6:.3f}, static FF {h['static_feedforward'] * 1e6:.3f}"
            f" ({c.reduction('static_feedforward'):.1f} %), GMS FF {h['gms_feedforward'] * 1e6:.3f}"
            f" ({c.reduction('gms_feedforward'):.1f} %), DOB {h['dob'] * 1e6:.3f}"
            f" ({c.reduction('dob'):.1f} %)"
        )

    def plot(self) -> dict[str, "Figure"]:
        return {**self.sinusoid.plot(), **self.circle.plot(), **self.compensation.plot()}


__all__ = ["ScenarioResult", "CircleResult", "CompensationResult", "GlitchStudy"]
