"""The result object shared by every identification step."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..results import Result, jsonable

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure

    from .paper import ReplaySettings


@dataclass
class IdentificationResult(Result):
    """Identified parameters with standard errors (the shared result protocol of
    :mod:`gmsfric.results`: ``to_dict``, ``to_json``, ``table``, ``plot``, ``save``).

    Attributes
    ----------
    model : str
        ``"static_map"``, ``"presliding"`` (GMS blocks), ``"plant"`` or ``"revised_plant"``.
    parameters : dict
        ``{name: (value, stderr)}`` in the data's own units (see ``units``).
    units : dict
        ``{name: unit string}``.
    info : dict
        JSON-able extras (number of points, fit cost, information criteria, ...).
    data : dict
        Arrays kept for the figures (not exported to JSON).
    model_object : object or None
        The identified model in SI (``StaticFriction``, ``GMS``, ``Plant``).
    covariance : (list of str, ndarray) or None
        Names and covariance matrix of the parameters, in the data's own units.
    provenance : dict
        Input files, columns, units and command line (see :func:`gmsfric.results.provenance`).
    diagnostics : list
        Findings about the fit's reliability (empty when there are none).
    """

    model: str
    parameters: dict[str, tuple[float, float]]
    units: dict[str, str] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)
    data: dict[str, Any] = field(default_factory=dict, repr=False)
    model_object: Any = field(default=None, repr=False)
    covariance: tuple[list[str], NDArray[np.float64]] | None = field(default=None, repr=False)
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    def __post_init__(self) -> None:
        # The SI model states the axis (and drive) its units are of, so that a rotary fit's
        # model stays rotary in Python and in every file written from it.
        obj = self.model_object
        if obj is not None and dataclasses.is_dataclass(obj) and "rotary" in {f.name for f in dataclasses.fields(obj)} and self.units:
            try:
                rotary, drive = self._axis()
            except (KeyError, ValueError):
                return
            extra = {"drive": drive} if "drive" in {f.name for f in dataclasses.fields(obj)} else {}
            self.model_object = dataclasses.replace(obj, rotary=rotary, **extra)

    @property
    def kind(self) -> str:  # type: ignore[override]
        return f"identify.{self.model}"

    def value(self, name: str) -> float:
        """The identified value of ``name``."""
        return self.parameters[name][0]

    def stderr(self, name: str) -> float:
        """The standard error of ``name``."""
        return self.parameters[name][1]

    @property
    def values(self) -> dict[str, float]:
        return {k: v for k, (v, _) in self.parameters.items()}

    def _body(self) -> dict[str, Any]:
        """``{"model", "parameters": {name: {"value", "stderr"}}, "units", ...info}``."""
        out: dict[str, Any] = {
            "model": self.model,
            "parameters": {k: {"value": jsonable(v), "stderr": jsonable(s)} for k, (v, s) in self.parameters.items()},
            "units": dict(self.units),
        }
        for k, v in self.info.items():
            if k not in out:
                out[k] = jsonable(v)
        return out

    def table(self) -> str:
        """A plain-text table ``name  value  stderr  unit``."""
        rows = [("parameter", "value", "stderr", "rel.", "unit")]
        for k, (v, s) in self.parameters.items():
            rel = f"{abs(s / v):.1%}" if v != 0 and np.isfinite(s) else "-"
            rows.append((k, f"{v:.6g}", f"{s:.3g}", rel, self.units.get(k, "")))
        widths = [max(len(r[i]) for r in rows) for i in range(5)]
        lines = [f"{self.model}"]
        for j, r in enumerate(rows):
            lines.append("  ".join(c.ljust(w) if i in (0, 4) else c.rjust(w) for i, (c, w) in enumerate(zip(r, widths))).rstrip())
            if j == 0:
                lines.append("  ".join("-" * w for w in widths))
        return "\n".join(lines)

    def plot(self) -> dict[str, "Figure"]:
        """The figures of this fit by file stem (matplotlib ``Figure`` objects, no pyplot)."""
        from .plots import figures

        return figures(self)

    def _quantities(self) -> dict[str, str]:
        if self.model == "static_map":
            return {"fc": "force", "fs": "force", "vs": "velocity", "sigma": "damping", "delta": "dimensionless"}
        if self.model == "presliding":
            return {k: ("stiffness" if k.startswith("k") else "force") for k in self.parameters}
        return {"a": "plant_gain", "b": "rate", "c": "rate_squared", "delay": "time"}

    def _axis(self) -> tuple[bool, str]:
        """(rotary, drive SI unit) read from the units of the fit."""
        from .. import units as _units

        if self.model == "static_map":
            return _units.is_rotary(self.units["vs"], "velocity"), "V"
        if self.model == "presliding":
            return _units.is_rotary(self.units["w1"], "force"), "V"
        a = _units.parse(self.units["a"])
        return a.dim[3] != 0, "A" if a.dim[4] != 0 else "V"

    def model_document(self) -> dict[str, Any] | None:
        """The ``gmsfric.model/1`` document of ``model_object`` (SI, units stated, covariance
        converted to SI, this result's provenance); ``None`` without a model object.  A plant
        identified without a force gain states none (it cannot be loaded as a Plant)."""
        if self.model_object is None:
            return None
        from .. import units as _units
        from ..model_io import model_to_dict

        rotary, drive = self._axis()
        cov = None
        if self.covariance is not None:
            names, matrix = self.covariance
            q = self._quantities()
            f = np.array([_units.factor(self.units[n], q[n]) for n in names])
            cov = (list(names), np.asarray(matrix) * np.outer(f, f), [_units.si_unit(q[n], rotary, drive=drive) for n in names])
        doc = model_to_dict(self.model_object, rotary=rotary, drive=drive, covariance=cov, provenance=self.provenance)
        if self.model in ("plant", "revised_plant") and self.info.get("force_gain") is None:
            del doc["parameters"]["force_gain"]
        return doc

    def _extras(self) -> dict[str, Any]:
        doc = self.model_document()
        return {} if doc is None else {"gmsfric_model": doc}


@dataclass
class Replay(Result):
    """Results of :func:`replay_paper` (the shared result protocol of :mod:`gmsfric.results`;
    JSON fields ``tables`` and ``truth``)."""

    kind = "paper"

    settings: "ReplaySettings"
    truth: dict[str, Any]
    static_map: IdentificationResult
    presliding: IdentificationResult
    plant: IdentificationResult
    revised_static: IdentificationResult
    revised_gms: IdentificationResult
    tables: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    provenance: dict[str, Any] = field(default_factory=dict, repr=False)
    diagnostics: list[Any] = field(default_factory=list, repr=False)

    def _body(self) -> dict[str, Any]:
        return {"tables": self.tables, "truth": self.truth}

    def models(self) -> dict[str, Any]:
        """The identified models (SI): static map, GMS, plant and the two revised plants."""
        parts = {"static_map": self.static_map, "gms": self.presliding, "plant": self.plant,
                 "revised_plant_static": self.revised_static, "revised_plant_gms": self.revised_gms}
        return {k: r.model_object for k, r in parts.items() if r.model_object is not None}

    def _extras(self) -> dict[str, Any]:
        from ..model_io import model_to_dict

        return {"gmsfric_model": model_to_dict(self.models(), provenance=self.provenance)}

    def plot(self) -> dict[str, Any]:
        """The paper's figures: Fig. 3, 5, 6, 7, 10, 11, 12, 13 equivalents."""
        figs = {}
        sm = self.static_map.plot()
        figs["fig5_static_map"] = sm["static_map_fit"]
        if "static_map_plateaus" in sm:
            figs["fig4_plateaus"] = sm["static_map_plateaus"]
        ps = self.presliding.plot()
        figs["fig7_virgin_curve"] = ps["presliding_virgin"]
        if "presliding_hysteresis" in ps:
            figs["fig6_hysteresis"] = ps["presliding_hysteresis"]
        figs["fig3_frf"] = self.plant.plot()["plant_bode"]
        rs = self.revised_static.plot()
        figs["fig10_combined_static"], figs["fig11_revised_static"] = rs["revised_plant_combined"], rs["revised_plant_revised"]
        rg = self.revised_gms.plot()
        figs["fig12_combined_gms"], figs["fig13_revised_gms"] = rg["revised_plant_combined"], rg["revised_plant_revised"]
        return figs

    #: The figures under their historical name.
    figures = plot

    def table(self) -> str:
        """Printed / true / identified values for every table of the paper."""
        return self.report()

    def report(self) -> str:
        """The tables as text (the same as :meth:`table`)."""
        lines = []
        for title, rows in self.tables.items():
            lines.append(title)
            head = ("parameter", "unit", "printed", "true", "identified", "stderr", "z")
            body = [
                (r["name"], r["unit"], _fmt(r["printed"]), _fmt(r["true"]), _fmt(r["value"]), _fmt(r["stderr"], 2), "-" if r["z"] is None else f"{r['z']:+.1f}")
                for r in rows
            ]
            widths = [max(len(x[i]) for x in [head] + body) for i in range(len(head))]
            lines.append("  " + "  ".join(h.ljust(w) if i < 2 else h.rjust(w) for i, (h, w) in enumerate(zip(head, widths))))
            for b in body:
                lines.append("  " + "  ".join(x.ljust(w) if i < 2 else x.rjust(w) for i, (x, w) in enumerate(zip(b, widths))))
            lines.append("")
        return "\n".join(lines)


def _fmt(v: Any, digits: int = 5) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    return f"{v:.{digits}g}"



def transform_covariance(cov: NDArray[np.float64], jac: NDArray[np.float64]) -> NDArray[np.float64]:
    """``J C J^T``: the covariance of ``y(x)`` from that of ``x`` to first order (``jac = dy/dx``).
    Entries that are infinite (undetermined directions) stay infinite instead of becoming NaN."""
    bad = ~np.isfinite(np.diag(cov))
    c = np.where(np.isfinite(cov), cov, 0.0)
    out = jac @ c @ jac.T
    hit = (np.abs(jac[:, bad]) > 0).any(axis=1) if bad.any() else np.zeros(out.shape[0], dtype=bool)
    out[hit, :] = np.inf
    out[:, hit] = np.inf
    return out


def covariance_from_jacobian(jac: NDArray[np.float64], residual: NDArray[np.float64], n_params: int | None = None) -> NDArray[np.float64]:
    """``s^2 (J^T J)^-1`` with ``s^2 = |r|^2 / (m - p)``.

    Columns are scaled to unit norm before the (pseudo-)inversion; directions the data do not
    determine (relative singular value below 1e-10) get infinite variance.
    """
    m, p = jac.shape
    p = n_params or p
    dof = max(m - p, 1)
    s2 = float(residual @ residual) / dof
    norms = np.linalg.norm(jac, axis=0)
    safe = np.where(norms > 0, norms, 1.0)
    js = jac / safe
    _, sv, vt = np.linalg.svd(js, full_matrices=False)
    good = sv > (sv.max() if sv.size else 0.0) * 1e-10
    inv = (vt[good].T / sv[good] ** 2) @ vt[good]
    cov = inv / np.outer(safe, safe)
    bad = np.zeros(jac.shape[1], dtype=bool)
    if not good.all():
        bad |= np.abs(vt[~good]).max(axis=0) > 1e-3
    bad |= norms == 0
    cov[bad, :] = np.inf
    cov[:, bad] = np.inf
    return cov * s2


def autocorrelation_inflation(residual: NDArray[np.float64], c: float = 5.0) -> float:
    """Integrated autocorrelation time ``1 + 2 sum_k rho_k`` of a residual series (Sokal's
    automatic window ``M >= c tau``), at least 1.

    A Jacobian covariance assumes white residuals; multiplying it by this factor accounts for
    residuals that are correlated in time (unmodelled sensor effects such as quantisation), so
    the reported standard errors stay honest.
    """
    r = np.asarray(residual, dtype=float)
    r = r - r.mean()
    n = r.size
    if n < 8 or not np.any(r):
        return 1.0
    m = 1 << int(np.ceil(np.log2(2 * n)))
    fr = np.fft.rfft(r, m)
    acf = np.fft.irfft(fr * np.conj(fr), m)[:n]
    acf /= acf[0]
    tau = 1.0
    for k in range(1, n):
        tau += 2.0 * acf[k]
        if k >= c * tau:
            break
    return float(max(tau, 1.0))
