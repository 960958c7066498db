"""The unit table: factors and dimensions, quantity checks, linear vs rotary, no silent factor 1."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from gmsfric import InvalidInputError, units
from gmsfric.units import UnitError


@pytest.mark.parametrize(
    "unit, quantity, factor",
    [
        ("mm", "position", 1e-3), ("um", "position", 1e-6), ("µm", "position", 1e-6), ("μm", "position", 1e-6),
        ("nm", "position", 1e-9), ("rad", "position", 1.0), ("deg", "position", math.pi / 180), ("mrad", "position", 1e-3),
        ("s", "time", 1.0), ("ms", "time", 1e-3), ("us", "time", 1e-6),
        ("N", "force", 1.0), ("mN", "force", 1e-3), ("kN", "force", 1e3),
        ("N m", "force", 1.0), ("N*m", "force", 1.0), ("Nm", "force", 1.0), ("mN m", "force", 1e-3),
        ("N/(mm/s)", "damping", 1e3), ("N s/mm", "damping", 1e3), ("N.s/mm", "damping", 1e3), ("Ns/mm", "damping", 1e3),
        ("N m s/rad", "damping", 1.0), ("mN/um", "stiffness", 1e3), ("N/um", "stiffness", 1e6), ("N m/rad", "stiffness", 1.0),
        ("mm/(V s^2)", "plant_gain", 1e-3), ("mm/V/s^2", "plant_gain", 1e-3), ("um/(V ms^2)", "plant_gain", 1.0),
        ("kg", "mass", 1.0), ("g", "mass", 1e-3), ("kg m^2", "mass", 1.0),
        ("V", "drive", 1.0), ("mV", "drive", 1e-3), ("A", "drive", 1.0),
        ("Hz", "frequency", 1.0), ("1/s", "rate", 1.0), ("1/ms", "rate", 1e3), ("1/s^2", "rate_squared", 1.0), ("1/s²", "rate_squared", 1.0),
        ("rpm", "velocity", 2 * math.pi / 60), ("mm/s", "velocity", 1e-3), ("(mm/s)/s", "acceleration", 1e-3),
        ("N/V", "force_gain", 1.0), ("N m/V", "force_gain", 1.0), ("1", "dimensionless", 1.0),
    ],
)
def test_factor_to_si(unit, quantity, factor):
    assert units.factor(unit, quantity) == pytest.approx(factor, rel=1e-15)


@pytest.mark.parametrize(
    "unit, quantity, rotary, match",
    [
        ("mm", "force", None, "`u`: unit 'mm' .*is not a force unit"),  # a force column declared in mm
        ("N/(mm/s)", "stiffness", None, "not a stiffness unit"),
        ("furlong/s", "velocity", None, "unknown unit 'furlong'"),
        ("N m", "force", False, "rotary-axis unit: mixing m and rad"),
        ("N", "force", True, "linear-axis unit"),
        ("rad", "position", False, "not a position unit on a linear axis"),
        ("m", "position", True, "on a rotary axis"),
        ("mm/V s^2", "plant_gain", None, "ambiguous"),
        ("m/s2", "velocity", None, "needs '\\^'"),
        ("", "force", None, "empty unit"),
        ("N^x", "force", None, "exponent must be an integer"),
        ("(mm/s", "velocity", None, "unexpected end"),
        ("2 m", "position", None, "number '2'"),
    ],
)
def test_bad_or_wrong_units_raise_naming_argument_unit_and_expectation(unit, quantity, rotary, match):
    with pytest.raises(UnitError, match=match) as info:
        units.to_si(1.0, unit, quantity, rotary=rotary, name="u")
    assert isinstance(info.value, InvalidInputError) and isinstance(info.value, ValueError)
    assert "`u`" in str(info.value)


def test_rotary_is_first_class_and_m_and_rad_never_mix():
    assert units.is_rotary("rad/s", "velocity") and not units.is_rotary("mm/s", "velocity")
    assert units.is_rotary("N m", "force") and not units.is_rotary("N", "force")
    assert units.si_unit("damping", rotary=True) == "N m s/rad" and units.si_unit("damping") == "N s/m"
    assert units.si_unit("mass", rotary=True) == "kg m^2"
    assert units.si_unit("plant_gain", drive="A") == "m/(A s^2)"
    # an angle is not a length even though rad is "dimensionless" in SI
    assert units.parse("rad").dim != units.parse("m").dim != units.parse("1").dim
    with pytest.raises(UnitError):
        units.to_si(1.0, "rad", "position", rotary=False)


@given(st.floats(min_value=-1e12, max_value=1e12, allow_nan=False), st.sampled_from(["mm/s", "um/s", "rad/s", "deg/s", "rpm", "m/s"]))
def test_to_si_and_from_si_are_inverse(x, unit):
    assert units.from_si(units.to_si(x, unit, "velocity"), unit, "velocity") == pytest.approx(x, rel=1e-14, abs=1e-300)


def test_arrays_and_scalars():
    out = units.to_si([1.0, 2.0], "mm", "position")
    assert isinstance(out, np.ndarray) and np.allclose(out, [1e-3, 2e-3])
    assert isinstance(units.to_si(3, "ms", "time"), float)


def test_ratio_and_display():
    assert units.ratio("N", "mm/s") == "N/(mm/s)" and units.ratio("N", "m") == "N/m" and units.ratio("N m", "rad") == "N m/rad"
    assert units.factor(units.ratio("mN", "um/ms"), "damping") == pytest.approx(1.0)
    assert units.display_unit("position") == "mm" and units.display_unit("velocity", rotary=True) == "rad/s"
    assert units.display_unit("position", rotary=True, angle="deg") == "deg"
    v, u = units.to_display(0.0125, "position")
    assert u == "mm" and v == pytest.approx(12.5)
    assert units.format_value(2.5, "force", rotary=True) == "2.5 N m"


def test_unknown_quantity_is_an_error():
    with pytest.raises(InvalidInputError, match="unknown quantity"):
        units.to_si(1.0, "m", "lenght")


@pytest.mark.parametrize("unit, quantity, rotary, expected", [
    ("N", "force", True, "expected N m "), ("N m", "force", False, "expected N, mN or kN "),
    ("m", "position", True, "expected rad or deg "), ("rad", "position", False, "expected m, mm or um"),
    ("N/m", "stiffness", True, "expected N m/rad "),
])
def test_the_expected_units_of_one_axis_never_list_the_refused_unit(unit, quantity, rotary, expected):
    with pytest.raises(UnitError) as info:
        units.check(unit, quantity, rotary=rotary, name="u")
    assert expected in str(info.value)
