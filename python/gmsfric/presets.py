"""Parameter sets from the paper and from the EMPS benchmark, converted to SI.

The paper ("Identification of Friction Models for Precise Positioning System in Machine Tools")
prints several quantities in units that cannot all be right.  Every reading below is an explicit
argument of :class:`PaperReading`, so a user who reads the paper differently changes one field
instead of a hidden constant.

Readings (default ``PaperReading()``):

* Table 1, static map.  Printed: Fc = 0.1826 N, Fs = 210 N, Vs = 450 mm/s, sigma = 6.9846 Ns/mm.
  Taken literally Fs is 1000x Fc, the Stribeck dip would lie far above the tested velocities
  (0.01..30 mm/s) and the viscous term would reach 210 N at 30 mm/s, against GMS break forces
  summing to 0.1058 N (Table 2).  The consistent reading, used by default, scales the three
  suspicious entries by 1e-3: ``fs_scale=1e-3`` (Fs = 0.210 N), ``vs_scale=1e-3``
  (Vs = 0.45 mm/s) and sigma in N s/m (``sigma_unit=1.0``: 6.9846 N s/m).  ``PaperReading.literal()``
  keeps the printed values.
* Table 2, GMS blocks.  alpha printed in N: ``w = (0.0330, 0.0570, 0.0132, 0.0026)`` N are taken as
  block break forces, ``alpha_i = w_i / sum(w)``.  ``gms_level="stribeck"`` (default) lets the
  blocks break at ``alpha_i s(v)`` with Table 1's Stribeck curve; ``"sum"`` rescales the curve to
  ``s(0) = sum(w) = 0.1058 N`` (eq. 6 calls ``sum W_i`` the break-away force).  k in N/mm -> N/m.
* Eq. 4 / the attraction parameter: the text says ``C = 1/Vs``; we use ``c = 1/Vs`` numerically
  with the Al-Bender time law (``slip_law="time"``, c in N/s), overridable with ``gms_c``.
* Eq. 1, plant: A = 19.85 mm/(V s^2) = 0.01985 m/(V s^2), B = 168.4 1/s, C = 176.8 1/s^2
  (the printed "V/s" units of B and C are read as 1/s and 1/s^2), delay 1.29 ms.
* Friction enters the plant input through the motor constant, which the paper does not give:
  ``force_per_volt`` (N/V), default 1.0.
* The DSP output (+-10 V) "is amplified by a factor of 10": the drive input of eq. 1 is limited to
  ``drive_limit = 100`` V.
* No controller is given: :func:`paper_pid` is ours (documented there).
* Table 3 (revised plants) is garbled: :class:`Table3Reading` holds the reading used everywhere.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any

from . import _gmsfric
from .models import GMS, StaticFriction, Stribeck
from .system import PID, Cascade, Plant

#: The reference numbers (the paper as printed, EMPS, the default reading), from the one data file
#: that the core's reference problems also read (``crates/gms-core/data/reference.json``).
REFERENCE: dict[str, Any] = json.loads(_gmsfric.reference_data())

_T1 = REFERENCE["paper"]["table1"]
PAPER_TABLE1 = {"fc": _T1["fc_N"], "fs": _T1["fs_printed"], "vs_mm_s": _T1["vs_printed_mm_per_s"], "sigma_N_s_per_mm": _T1["sigma_printed_N_s_per_mm"], "delta": _T1["delta"]}
PAPER_TABLE2_W_N = tuple(REFERENCE["paper"]["table2"]["w_N"])
PAPER_TABLE2_K_N_PER_MM = tuple(REFERENCE["paper"]["table2"]["k_N_per_mm"])
_EQ1 = REFERENCE["paper"]["eq1"]
PAPER_EQ1 = {"a_mm": _EQ1["a_mm_per_V_s2"], "b": _EQ1["b_per_s"], "c": _EQ1["c_per_s2"], "delay": _EQ1["delay_s"]}
_READING = REFERENCE["paper"]["reading"]


@dataclass(frozen=True)
class PaperReading:
    """How the paper's printed numbers are turned into SI parameters (see the module doc)."""

    fs_scale: float = _READING["fs_scale"]
    vs_scale: float = _READING["vs_scale"]
    sigma_unit: float = _READING["sigma_unit"]
    gms_level: str = "stribeck"
    gms_c: float | None = None
    slip_law: str = "time"
    force_per_volt: float = _READING["force_per_volt"]
    drive_limit: float = _READING["drive_limit_V"]

    @classmethod
    def literal(cls) -> "PaperReading":
        """The numbers exactly as printed (Fs = 210 N, Vs = 0.45 m/s, sigma = 6984.6 N s/m)."""
        return cls(fs_scale=1.0, vs_scale=1.0, sigma_unit=1e3)


def paper_stribeck(reading: PaperReading = PaperReading()) -> Stribeck:
    """Table 1's Stribeck curve under ``reading``."""
    t = PAPER_TABLE1
    return Stribeck(fc=t["fc"], fs=t["fs"] * reading.fs_scale, vs=t["vs_mm_s"] * 1e-3 * reading.vs_scale, delta=t["delta"])


def paper_static_friction(reading: PaperReading = PaperReading()) -> StaticFriction:
    """Table 1's static map ``F(v)`` under ``reading``."""
    return StaticFriction(paper_stribeck(reading), sigma=PAPER_TABLE1["sigma_N_s_per_mm"] * reading.sigma_unit)


def paper_gms(reading: PaperReading = PaperReading()) -> GMS:
    """Table 2's four-block GMS under ``reading``."""
    st = paper_stribeck(reading)
    c = reading.gms_c if reading.gms_c is not None else 1.0 / st.vs
    return GMS.from_break_forces(
        [k * 1e3 for k in PAPER_TABLE2_K_N_PER_MM],
        PAPER_TABLE2_W_N,
        c,
        stribeck=st,
        sigma=PAPER_TABLE1["sigma_N_s_per_mm"] * reading.sigma_unit,
        slip_law=reading.slip_law,  # type: ignore[arg-type]
        scale=reading.gms_level,  # type: ignore[arg-type]
    )


def paper_plant(reading: PaperReading = PaperReading()) -> Plant:
    """Eq. 1 in SI with the 1.29 ms delay."""
    e = PAPER_EQ1
    return Plant(a=e["a_mm"] * 1e-3, b=e["b"], c=e["c"], delay=e["delay"], force_gain=reading.force_per_volt)


def paper_pid(reading: PaperReading = PaperReading()) -> PID:
    """A PID for the paper's axis (the paper gives none): ~10 Hz bandwidth, ~65 deg phase margin,
    integral zero at 5 rad/s, derivative filtered at 0.5 ms.

    The output is limited to ``reading.drive_limit`` volts: the DSP's +-10 V times the x10
    amplifier the paper mentions.  (Eq. 1 has a DC gain a/c = 0.11 mm/V, so holding the 10 mm
    reference of Section 4.2 takes about 89 V: the limit must be the amplified one.)"""
    lim = reading.drive_limit
    g = REFERENCE["paper"]["pid"]
    return PID(kp=g["kp"], ki=g["ki"], kd=g["kd"], tf=g["tf_s"], u_min=-lim, u_max=lim)


@dataclass(frozen=True)
class Table3Reading:
    """How the garbled Table 3 (the revised plants of Section 4.1) is read, in the paper's units:
    ``(A', B', C')`` per friction model in mm/(V s^2), 1/s, 1/s^2.

    The extracted text is ``A' 19.85 | A 19.85 180.40 | B' 2.40 | B 168.40 168.40 176.80 |
    C' 176.80 | C 176.80 176.80``: ten numbers for twelve cells (rows A', A, B', B, C', C; columns
    static model, GMS model). Default: the rows carry (static, GMS) with one original A and one
    original B lost, so the static model is revised to B' = 2.40 (the text says the static model's
    FRF "clearly" differed and was revised) and the GMS model to A' = 180.40; C is unchanged.
    :meth:`static_unchanged` is the other reading that fits the count: the lost cells are the
    static model's A', B' (unchanged) and the GMS column holds A' = 180.40, B' = 2.40.
    """

    static: tuple[float, float, float] = tuple(REFERENCE["paper"]["table3"]["static"])  # type: ignore[assignment]
    gms: tuple[float, float, float] = tuple(REFERENCE["paper"]["table3"]["gms"])  # type: ignore[assignment]

    @classmethod
    def static_unchanged(cls) -> "Table3Reading":
        alt = REFERENCE["paper"]["table3"]["static_unchanged"]
        return cls(static=tuple(alt["static"]), gms=tuple(alt["gms"]))  # type: ignore[arg-type]

    def plant(self, model: str, reading: PaperReading = PaperReading()) -> Plant:
        """The revised plant for ``model`` (``"static"`` or ``"gms"``) in SI, with eq. 1's delay."""
        if model not in ("static", "gms"):
            from .errors import InvalidInputError

            raise InvalidInputError(f"`model` must be 'static' or 'gms', got {model!r}")
        a, b, c = self.static if model == "static" else self.gms
        return Plant(a=a * 1e-3, b=b, c=c, delay=PAPER_EQ1["delay"], force_gain=reading.force_per_volt)


# --- EMPS benchmark (Janot, Gautier, Brunot 2019) ------------------------------------------------

_EMPS = REFERENCE["emps"]
EMPS_GTAU = _EMPS["gtau_N_per_V"]
EMPS_KP = _EMPS["kp_per_s"]
EMPS_KV = _EMPS["kv_V_s_per_m"]
EMPS_DRIVE_LIMIT = _EMPS["drive_limit_V"]
_RM = _EMPS["reference_model"]
EMPS_REFERENCE_MODEL = {"M": _RM["M_kg"], "Fv": _RM["Fv_N_s_per_m"], "Fc": _RM["Fc_N"], "offset": _RM["offset_N"]}


def emps_plant() -> Plant:
    """EMPS rigid axis: mass 95.11 kg driven by ``gtau = 35.15 N/V``; viscous friction lives in
    the friction model, not the plant."""
    return Plant.from_mass(EMPS_REFERENCE_MODEL["M"], force_gain=EMPS_GTAU)


def emps_friction() -> StaticFriction:
    """EMPS reference friction ``Fv qd + Fc sign(qd) + offset`` (no Stribeck dip)."""
    m = EMPS_REFERENCE_MODEL
    return StaticFriction(Stribeck(m["Fc"], m["Fc"], 1.0), sigma=m["Fv"], offset=m["offset"])


def emps_controller() -> Cascade:
    """EMPS cascade controller with the 10 V drive limit."""
    return Cascade(kp=EMPS_KP, kv=EMPS_KV, u_min=-EMPS_DRIVE_LIMIT, u_max=EMPS_DRIVE_LIMIT)


__all__ = [
    "PaperReading",
    "Table3Reading",
    "paper_stribeck",
    "paper_static_friction",
    "paper_gms",
    "paper_plant",
    "paper_pid",
    "emps_plant",
    "emps_friction",
    "emps_controller",
]
