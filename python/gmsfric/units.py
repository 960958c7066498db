"""The one unit table of gmsfric: unit strings -> (factor to SI, dimension), checked against the
quantity they are declared for.

Files and command lines may use any unit; everything inside is SI (m, rad, kg, s, N, N m, V, A).
A unit string is parsed into a factor to SI and a dimension over six base dimensions: length,
mass, time, angle (kept apart from length so that ``m`` and ``rad`` never mix), current and the
"drive input" (volts of a drive command).  Products, quotients, powers and parentheses are
accepted: ``mm``, ``N s/mm``, ``N/(mm/s)``, ``mN/um``, ``N m/rad``, ``mm/(V s^2)``, ``kg m^2``,
``1/s^2``, ``rpm`` ...  A product right after a quotient (``mm/V s^2``) is ambiguous and refused.

:func:`to_si` / :func:`from_si` convert values for a named *quantity* ("position", "force",
"stiffness", "plant_gain", ...) of a linear or a rotary axis; a unit that is unknown or does not
measure that quantity raises :class:`UnitError` naming the argument, the unit and what was
expected.  There is no silent factor of 1.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from functools import lru_cache
from typing import Iterable, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._validate import choice
from .errors import InvalidInputError

__all__ = [
    "UnitError",
    "Unit",
    "parse",
    "to_si",
    "from_si",
    "factor",
    "si_unit",
    "drive_base",
    "drive_of",
    "DRIVES",
    "is_rotary",
    "check",
    "ratio",
    "display_unit",
    "to_display",
    "format_value",
    "QUANTITIES",
]


class UnitError(InvalidInputError):
    """A unit string is unknown, malformed, or does not measure the expected quantity."""


Dim = tuple[int, int, int, int, int, int]
BASE = ("length", "mass", "time", "angle", "current", "drive")
_ONE: Dim = (0, 0, 0, 0, 0, 0)


def _dim(L: int = 0, M: int = 0, T: int = 0, A: int = 0, I: int = 0, U: int = 0) -> Dim:  # noqa: E741
    return (L, M, T, A, I, U)


def _mul(a: Dim, b: Dim, sign: int = 1) -> Dim:
    return tuple(x + sign * y for x, y in zip(a, b))  # type: ignore[return-value]


def _pow(a: Dim, n: int) -> Dim:
    return tuple(x * n for x in a)  # type: ignore[return-value]


_L, _M, _T, _A, _I, _U = (_dim(L=1), _dim(M=1), _dim(T=1), _dim(A=1), _dim(I=1), _dim(U=1))
_N = _dim(L=1, M=1, T=-2)
_MICRO = ("u", "µ", "μ")  # ASCII u, micro sign U+00B5, Greek mu U+03BC

#: Every unit symbol: factor to SI and dimension.  Case-sensitive (``ns`` nanosecond, ``Ns`` newton second).
UNITS: dict[str, tuple[float, Dim]] = {
    "1": (1.0, _ONE),
    "%": (1e-2, _ONE),
    # length
    "m": (1.0, _L), "km": (1e3, _L), "cm": (1e-2, _L), "mm": (1e-3, _L), "nm": (1e-9, _L),
    # angle
    "rad": (1.0, _A), "mrad": (1e-3, _A), "deg": (math.pi / 180.0, _A), "°": (math.pi / 180.0, _A),
    "rev": (2.0 * math.pi, _A), "arcsec": (math.pi / 648000.0, _A),
    # time, frequency
    "s": (1.0, _T), "ms": (1e-3, _T), "ns": (1e-9, _T), "min": (60.0, _T), "h": (3600.0, _T),
    "Hz": (1.0, _pow(_T, -1)), "kHz": (1e3, _pow(_T, -1)),
    "rpm": (2.0 * math.pi / 60.0, _mul(_A, _T, -1)),
    # mass, force, torque
    "kg": (1.0, _M), "g": (1e-3, _M), "mg": (1e-6, _M),
    "N": (1.0, _N), "mN": (1e-3, _N), "kN": (1e3, _N),
    "Nm": (1.0, _mul(_N, _L)), "Ns": (1.0, _mul(_N, _T)),
    # electrical: the drive input (command volts) and current
    "V": (1.0, _U), "mV": (1e-3, _U), "kV": (1e3, _U),
    "A": (1.0, _I), "mA": (1e-3, _I),
}
for _p in _MICRO:
    UNITS[f"{_p}m"] = (1e-6, _L)
    UNITS[f"{_p}rad"] = (1e-6, _A)
    UNITS[f"{_p}s"] = (1e-6, _T)
    UNITS[f"{_p}N"] = (1e-6, _N)
    UNITS[f"{_p}V"] = (1e-6, _U)
    UNITS[f"{_p}A"] = (1e-6, _I)


@dataclass(frozen=True)
class Unit:
    """A parsed unit: ``value_SI = value * factor``; ``dim`` are the exponents of :data:`BASE`."""

    text: str
    factor: float
    dim: Dim

    def describe(self) -> str:
        """The dimension in words, e.g. ``length time^-1``."""
        parts = [n if e == 1 else f"{n}^{e}" for n, e in zip(BASE, self.dim) if e]
        return " ".join(parts) or "dimensionless"


# ------------------------------------------------------------------------------------------
# parser: expr := factor (('*' | '.' | ' ') factor | '/' factor)*, factor := atom [('^'|'**') int]

_TOKEN = re.compile(r"\s*(?:(?P<num>[+-]?\d+)|(?P<name>[A-Za-zµμ°%][A-Za-zµμ°%]*)|(?P<op>\*\*|[*/^().·⋅]))")
_SUPERSCRIPTS = str.maketrans({"²": "^2", "³": "^3", "⁻": "^-"})


class _Parser:
    def __init__(self, text: str, name: str) -> None:
        self.text, self.name = text, name
        src = text.replace("⁻¹", "^-1").translate(_SUPERSCRIPTS).replace("^-^", "^-")
        self.tokens: list[tuple[str, str]] = []
        pos = 0
        while pos < len(src):
            if src[pos:].strip() == "":
                break
            m = _TOKEN.match(src, pos)
            if m is None or m.end() == pos:
                self.fail(f"unexpected character {src[pos:].strip()[0]!r}")
            assert m is not None
            kind = m.lastgroup or ""
            self.tokens.append((kind, m.group(kind)))
            # two names or a name and a number side by side: implicit product ("N m", "kg m^2")
            pos = m.end()
        self.i = 0

    def fail(self, why: str) -> None:
        raise UnitError(f"`{self.name}`: cannot read unit {self.text!r}: {why}")

    def peek(self) -> tuple[str, str] | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self) -> tuple[str, str]:
        tok = self.peek()
        if tok is None:
            self.fail("unexpected end")
        self.i += 1
        return tok  # type: ignore[return-value]

    def parse(self) -> tuple[float, Dim]:
        if not self.tokens:
            self.fail("empty unit (use '1' for a dimensionless quantity)")
        f, d = self.expr()
        if self.peek() is not None:
            self.fail(f"unexpected {self.peek()[1]!r}")  # type: ignore[index]
        return f, d

    def _starts_factor(self, tok: tuple[str, str] | None) -> bool:
        return tok is not None and (tok[0] in ("name", "num") or tok[1] == "(")

    def expr(self) -> tuple[float, Dim]:
        f, d = self.factor()
        after_slash = False
        while True:
            tok = self.peek()
            if tok is None or tok[1] == ")":
                return f, d
            if tok[1] == "/":
                self.take()
                g, e = self.factor()
                f, d = f / g, _mul(d, e, -1)
                after_slash = True
                continue
            explicit = tok[1] in ("*", ".", "·", "⋅")
            if tok[0] == "num" and not explicit:
                self.fail(f"a number after a unit needs '^' (write '...^{tok[1]}')")
            if explicit:
                self.take()
            elif not self._starts_factor(tok):
                self.fail(f"unexpected {tok[1]!r}")
            if after_slash:
                # "mm/V s^2": a/(b c) or (a/b) c?  Refuse rather than guess.
                self.fail("a product after '/' is ambiguous; use parentheses, e.g. 'mm/(V s^2)' or 'N s/mm'")
            g, e = self.factor()
            f, d = f * g, _mul(d, e)

    def factor(self) -> tuple[float, Dim]:
        f, d = self.atom()
        tok = self.peek()
        if tok is not None and tok[1] in ("^", "**"):
            self.take()
            kind, val = self.take()
            if kind != "num":
                self.fail(f"exponent must be an integer, got {val!r}")
            n = int(val)
            f, d = f**n, _pow(d, n)
        return f, d

    def atom(self) -> tuple[float, Dim]:
        kind, val = self.take()
        if val == "(":
            f, d = self.expr()
            if self.take()[1] != ")":
                self.fail("missing ')'")
            return f, d
        if kind == "num":
            if val != "1":
                self.fail(f"number {val!r} in a unit (only '1', as in '1/s', is allowed)")
            return 1.0, _ONE
        if kind == "name":
            if val not in UNITS:
                self.fail(f"unknown unit {val!r}")
            return UNITS[val]
        self.fail(f"unexpected {val!r}")
        raise AssertionError  # pragma: no cover


@lru_cache(maxsize=512)
def _parse_cached(text: str) -> tuple[float, Dim]:
    return _Parser(text, "unit").parse()


def parse(unit: str, name: str = "unit") -> Unit:
    """Parse ``unit`` into a :class:`Unit` (raises :class:`UnitError` naming ``name``)."""
    if not isinstance(unit, str):
        raise UnitError(f"`{name}` must be a unit string, got {type(unit).__name__}")
    text = unit.strip()
    try:
        f, d = _parse_cached(text)
    except UnitError as exc:
        raise UnitError(str(exc).replace("`unit`", f"`{name}`", 1)) from None
    return Unit(text, f, d)


# ------------------------------------------------------------------------------------------
# quantities: the dimensions a declared unit may have, for a linear and a rotary axis

_F_ROT = _mul(_N, _L)  # torque, N m


def _per_drive(d: Dim, force: Dim) -> tuple[Dim, Dim, Dim]:
    """``d`` per unit of drive input: a voltage, a current, or a force (``force``: N, or N m on a
    rotary axis) when the run's drive command is the force itself (``force_gain`` 1 N/N)."""
    return (_mul(d, _U, -1), _mul(d, _I, -1), _mul(d, force, -1))


@dataclass(frozen=True)
class Quantity:
    """Accepted dimensions of a quantity on a linear and on a rotary axis, and their SI units."""

    name: str
    linear: tuple[Dim, ...]
    rotary: tuple[Dim, ...]
    si_linear: str
    si_rotary: str
    example: str


def _q(name: str, lin: Dim | tuple[Dim, ...], rot: Dim | tuple[Dim, ...], si_lin: str, si_rot: str, example: str) -> Quantity:
    as_t = (lambda d: d if isinstance(d[0], tuple) else (d,))  # noqa: E731
    return Quantity(name, as_t(lin), as_t(rot), si_lin, si_rot, example)  # type: ignore[arg-type]


_RATE = _pow(_T, -1)
QUANTITIES: dict[str, Quantity] = {
    q.name: q
    for q in (
        _q("position", _L, _A, "m", "rad", "m, mm, um or rad, deg"),
        _q("velocity", _mul(_L, _T, -1), _mul(_A, _T, -1), "m/s", "rad/s", "m/s, mm/s or rad/s, rpm"),
        _q("acceleration", _mul(_L, _pow(_T, 2), -1), _mul(_A, _pow(_T, 2), -1), "m/s^2", "rad/s^2", "m/s^2 or rad/s^2"),
        _q("force", _N, _F_ROT, "N", "N m", "N, mN, kN or N m (torque)"),
        _q("stiffness", _mul(_N, _L, -1), _mul(_F_ROT, _A, -1), "N/m", "N m/rad", "N/m, N/um, mN/um or N m/rad"),
        _q("damping", _mul(_mul(_N, _T), _L, -1), _mul(_mul(_F_ROT, _T), _A, -1), "N s/m", "N m s/rad", "N s/m, N s/mm, N/(mm/s) or N m s/rad"),
        # rotary mass: inertia kg m^2, or written as torque per angular acceleration (N m s^2/rad)
        _q("mass", _M, (_mul(_M, _pow(_L, 2)), _mul(_mul(_M, _pow(_L, 2)), _A, -1)), "kg", "kg m^2", "kg, g or kg m^2"),
        _q("time", _T, _T, "s", "s", "s, ms, us"),
        _q("frequency", _RATE, _RATE, "Hz", "Hz", "Hz, kHz, 1/s"),
        _q("rate", _RATE, _RATE, "1/s", "1/s", "1/s, 1/ms"),
        _q("rate_squared", _pow(_T, -2), _pow(_T, -2), "1/s^2", "1/s^2", "1/s^2"),
        _q("dimensionless", _ONE, _ONE, "1", "1", "1 or %"),
        _q("drive", (_U, _I), (_U, _I), "V", "V", "V, mV (a drive command) or A"),
        _q("voltage", _U, _U, "V", "V", "V, mV"),
        _q("current", _I, _I, "A", "A", "A, mA"),
        _q("plant_gain", _per_drive(_mul(_L, _pow(_T, 2), -1), _N), _per_drive(_mul(_A, _pow(_T, 2), -1), _F_ROT), "m/(V s^2)", "rad/(V s^2)",
           "m/(V s^2), mm/(V s^2), m/(N s^2) or rad/(V s^2)"),
        _q("force_gain", _per_drive(_N, _N), _per_drive(_F_ROT, _F_ROT), "N/V", "N m/V", "N/V, N/A, N/N or N m/V"),
        _q("force_rate", _mul(_N, _T, -1), _mul(_F_ROT, _T, -1), "N/s", "N m/s", "N/s or N m/s"),
        _q("inverse_position", _pow(_L, -1), _pow(_A, -1), "1/m", "1/rad", "1/m or 1/rad"),
        # a viscous coefficient per unit of speed (heating: viscous shift per m/s of low-passed speed)
        _q("damping_per_velocity", _mul(_mul(_N, _pow(_T, 2)), _pow(_L, -2)), _mul(_mul(_F_ROT, _pow(_T, 2)), _pow(_A, -2)),
           "N s^2/m^2", "N m s^2/rad^2", "N s^2/m^2 or N m s^2/rad^2"),
    )
}

_DRIVE_SENSITIVE = {"drive", "plant_gain", "force_gain"}


def _quantity(quantity: str) -> Quantity:
    if quantity not in QUANTITIES:
        raise InvalidInputError(f"unknown quantity {quantity!r}; known: {', '.join(QUANTITIES)}")
    return QUANTITIES[quantity]


def _classify(u: Unit, q: Quantity) -> tuple[bool, bool]:
    return u.dim in q.linear, u.dim in q.rotary


def check(unit: str, quantity: str, *, rotary: bool | None = None, name: str = "unit") -> Unit:
    """Parse ``unit`` and check that it measures ``quantity`` (on a rotary axis when ``rotary``
    is True, a linear one when False, either when None).

    Raises
    ------
    UnitError
        Unknown or malformed unit, or a unit of another quantity (e.g. a force declared in mm).
    """
    q = _quantity(quantity)
    u = parse(unit, name)
    lin, rot = _classify(u, q)
    ok = (lin or rot) if rotary is None else (rot if rotary else lin)
    if not ok:
        axis = "" if rotary is None or q.linear == q.rotary else (" on a rotary axis" if rotary else " on a linear axis")
        what = u.describe()
        hint = ""
        if rotary is not None and (lin or rot):
            hint = f" (that is a {'linear' if lin else 'rotary'}-axis unit: mixing m and rad is not allowed)"
        expected = q.example if rotary is None else _examples(q, rotary)
        raise UnitError(f"`{name}`: unit {unit!r} ({what}) is not a {quantity.replace('_', ' ')} unit{axis}; expected {expected}{hint}")
    return u


@lru_cache(maxsize=128)
def _examples(q: Quantity, rotary: bool) -> str:
    """The examples of ``q`` that fit one axis kind ("N m" for a rotary force, never "N")."""
    dims = q.rotary if rotary else q.linear
    keep = []
    for text in re.split(r",\s*|\s+or\s+", q.example):
        text = re.sub(r"\s+\(.*?\)$", "", text).strip()
        try:
            if text and parse(text).dim in dims:
                keep.append(text)
        except UnitError:
            continue
    if not keep:
        keep = [q.si_rotary if rotary else q.si_linear]
    return keep[0] if len(keep) == 1 else f"{', '.join(keep[:-1])} or {keep[-1]}"


def is_rotary(unit: str, quantity: str, *, name: str = "unit") -> bool:
    """Whether ``unit`` is the rotary-axis form of ``quantity`` (rad rather than m, N m rather
    than N).  Raises :class:`UnitError` if it measures neither form."""
    q = _quantity(quantity)
    u = check(unit, quantity, name=name)
    lin, rot = _classify(u, q)
    return rot and not lin


def factor(unit: str, quantity: str, *, rotary: bool | None = None, name: str = "unit") -> float:
    """The factor ``f`` with ``value_SI = value * f`` for ``unit`` declared as ``quantity``."""
    return check(unit, quantity, rotary=rotary, name=name).factor


@overload
def to_si(values: float, unit: str, quantity: str, *, rotary: bool | None = ..., name: str = ...) -> float: ...
@overload
def to_si(values: ArrayLike, unit: str, quantity: str, *, rotary: bool | None = ..., name: str = ...) -> NDArray[np.float64] | float: ...


def to_si(values: ArrayLike, unit: str, quantity: str, *, rotary: bool | None = None, name: str = "unit") -> NDArray[np.float64] | float:
    """``values`` given in ``unit`` converted to SI, after checking ``unit`` measures ``quantity``.

    Parameters
    ----------
    values : float or array_like
    unit : str
        E.g. ``"mm/s"``, ``"N/(mm/s)"``, ``"mN/um"``, ``"N m/rad"``.
    quantity : str
        One of :data:`QUANTITIES` (``"position"``, ``"velocity"``, ``"force"``, ``"stiffness"``,
        ``"damping"``, ``"mass"``, ``"time"``, ``"frequency"``, ``"plant_gain"``, ...).
    rotary : bool, optional
        Require the rotary (True) or linear (False) form; None accepts either.
    name : str
        Argument name used in the error message.

    Returns
    -------
    float or ndarray
        A float for a scalar input, else a float64 array.
    """
    f = factor(unit, quantity, rotary=rotary, name=name)
    if np.isscalar(values):
        return float(values) * f  # type: ignore[arg-type]
    return np.asarray(values, dtype=np.float64) * f


def from_si(values: ArrayLike, unit: str, quantity: str, *, rotary: bool | None = None, name: str = "unit") -> NDArray[np.float64] | float:
    """The inverse of :func:`to_si`: SI ``values`` expressed in ``unit``."""
    f = factor(unit, quantity, rotary=rotary, name=name)
    if np.isscalar(values):
        return float(values) / f  # type: ignore[arg-type]
    return np.asarray(values, dtype=np.float64) / f


#: SI drive units: a voltage or a current command, or the force itself (N; N m on a rotary axis)
#: when a run gives its drive as a force column.
DRIVES = ("V", "A", "N", "N m")

#: SI units of the drive-dependent quantities when the drive command is a force.
_FORCE_DRIVEN = {
    False: {"drive": "N", "plant_gain": "m/(N s^2)", "force_gain": "N/N"},
    True: {"drive": "N m", "plant_gain": "rad/(N m s^2)", "force_gain": "N m/(N m)"},
}


def _check_drive(drive: str, rotary: bool) -> None:
    choice("drive", drive, DRIVES)
    if drive in ("N", "N m") and (drive == "N m") != bool(rotary):
        raise UnitError(f"`drive`: a force drive is {'N m (a torque)' if rotary else 'N'} on a {'rotary' if rotary else 'linear'} axis, got {drive!r}")


def si_unit(quantity: str, rotary: bool = False, *, drive: str = "V") -> str:
    """The SI unit string of ``quantity`` (``"N s/m"``; rotary ``"N m s/rad"``).  ``drive`` is the
    drive input's SI unit (one of :data:`DRIVES`: ``"V"``, ``"A"``, or ``"N"`` / ``"N m"`` for a
    force command on a linear / rotary axis) for the drive-dependent quantities."""
    q = _quantity(quantity)
    s = q.si_rotary if rotary else q.si_linear
    if quantity in _DRIVE_SENSITIVE:
        _check_drive(drive, rotary)
        if drive in ("N", "N m"):
            return _FORCE_DRIVEN[bool(rotary)][quantity]
        s = s.replace("V", drive)
    return s


def drive_base(unit: str, *, name: str = "unit") -> str:
    """The SI drive unit (one of :data:`DRIVES`) of a drive-input unit: ``mV`` -> ``V``, ``mA``
    -> ``A``, and a force unit (a drive command that is the force itself) ``mN`` -> ``N``,
    ``N mm`` -> ``N m``."""
    u = parse(unit, name)
    if u.dim == _N:
        return "N"
    if u.dim == _F_ROT:
        return "N m"
    u = check(unit, "drive", name=name)
    return "V" if u.dim == _U else "A"


def drive_of(unit: str, quantity: str, *, rotary: bool, name: str = "unit") -> str:
    """The SI drive unit (one of :data:`DRIVES`) a ``plant_gain`` or ``force_gain`` unit is per:
    ``mm/(V s^2)`` -> ``V``, ``N/A`` -> ``A``, ``N/N`` -> ``N`` (``N m`` on a rotary axis)."""
    if quantity not in ("plant_gain", "force_gain"):
        raise InvalidInputError(f"`quantity` must be \"plant_gain\" or \"force_gain\", got {quantity!r}")
    u = check(unit, quantity, rotary=rotary, name=name)
    q = QUANTITIES[quantity]
    dims = q.rotary if rotary else q.linear
    return ("V", "A", "N m" if rotary else "N")[dims.index(u.dim)]


def ratio(numerator: str, denominator: str) -> str:
    """``numerator/denominator`` as a unit string, parenthesising a compound denominator
    (``ratio("N", "mm/s") == "N/(mm/s)"``)."""
    den = denominator.strip()
    if re.search(r"[\s/*.·^]", den):
        den = f"({den})"
    return f"{numerator.strip()}/{den}"


# ------------------------------------------------------------------------------------------
# display: preferred units in reports and figures

_DISPLAY_LINEAR = {
    "position": "mm", "velocity": "mm/s", "acceleration": "mm/s^2", "force": "N", "stiffness": "N/um",
    "damping": "N s/m", "mass": "kg", "time": "s", "frequency": "Hz", "rate": "1/s", "rate_squared": "1/s^2",
    "dimensionless": "1", "drive": "V", "voltage": "V", "current": "A", "plant_gain": "mm/(V s^2)",
    "force_gain": "N/V", "force_rate": "N/s", "inverse_position": "1/mm", "damping_per_velocity": "N s^2/m^2",
}
_DISPLAY_ROTARY = {
    **_DISPLAY_LINEAR,
    "position": "rad", "velocity": "rad/s", "acceleration": "rad/s^2", "force": "N m", "stiffness": "N m/rad",
    "damping": "N m s/rad", "mass": "kg m^2", "plant_gain": "rad/(V s^2)", "force_gain": "N m/V", "force_rate": "N m/s",
    "inverse_position": "1/rad", "damping_per_velocity": "N m s^2/rad^2",
}
_DEGREES = {"position": "deg", "velocity": "deg/s", "acceleration": "deg/s^2", "stiffness": "N m/deg", "damping": "N m s/deg",
            "plant_gain": "deg/(V s^2)", "inverse_position": "1/deg"}


def display_unit(quantity: str, rotary: bool = False, *, angle: str = "rad") -> str:
    """The preferred unit for showing ``quantity`` in reports: mm, mm/s, N, N/um ... on a linear
    axis; rad (or deg with ``angle="deg"``), rad/s, N m ... on a rotary one."""
    _quantity(quantity)
    choice("angle", angle, ("rad", "deg"))
    if rotary and angle == "deg" and quantity in _DEGREES:
        return _DEGREES[quantity]
    return (_DISPLAY_ROTARY if rotary else _DISPLAY_LINEAR)[quantity]


def to_display(values: ArrayLike, quantity: str, rotary: bool = False, *, angle: str = "rad") -> tuple[NDArray[np.float64] | float, str]:
    """SI ``values`` of ``quantity`` in the preferred display unit: ``(values, unit)``."""
    unit = display_unit(quantity, rotary, angle=angle)
    return from_si(values, unit, quantity, rotary=rotary), unit


def format_value(value: float, quantity: str, rotary: bool = False, *, digits: int = 4, angle: str = "rad") -> str:
    """``"12.35 mm"``: an SI value in its display unit."""
    v, unit = to_display(float(value), quantity, rotary, angle=angle)
    return f"{v:.{digits}g} {unit}" if unit != "1" else f"{v:.{digits}g}"


def known_units() -> Iterable[str]:
    """Every unit symbol the parser knows."""
    return tuple(UNITS)
