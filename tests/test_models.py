"""Physics properties of the friction models through the Python API."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import gmsfric as g
from gmsfric import presets


def _gms(k, w, fc_ratio=0.8, vs=1e-3, c=1e3):
    w = np.asarray(w)
    strb = g.Stribeck(fc=fc_ratio * w.sum(), fs=w.sum(), vs=vs)
    return g.GMS(strb, k, w / w.sum(), c=c, sigma=2.0)


blocks = st.lists(
    st.tuples(st.floats(1e3, 1e7), st.floats(0.01, 5.0)),
    min_size=1,
    max_size=6,
)


@given(blocks, st.floats(1e-5, 5e-2), st.sampled_from([1.0, -1.0]))
def test_gms_settles_on_static_map_at_constant_velocity(bl, speed, direction):
    k, w = zip(*bl)
    m = _gms(k, w)
    v = direction * speed
    travel = 50 * max(wi / ki for ki, wi in bl) + 200 * speed / m.c * m.stribeck.fs
    t = np.linspace(0.0, travel / speed + 1.0, 5001)
    f = g.simulate_friction(m, t, v * t)
    assert f[-1] == pytest.approx(m.static_map().force([v])[0], rel=1e-6)


@given(blocks)
def test_quasi_static_virgin_curve(bl):
    k, w = zip(*bl)
    m = _gms(k, w)
    x_max = 2 * max(wi / ki for ki, wi in bl)
    x = np.linspace(0, x_max, 3001)
    t = np.linspace(0, 1e4, x.size)  # nm/s scale: quasi-static
    f = g.simulate_friction(m, t, x)
    np.testing.assert_allclose(f, m.virgin_curve(x), atol=2e-3 * sum(w))


def test_masing_rule_and_inner_loop_closure_for_paper_gms():
    m = presets.paper_gms()
    xr = 8e-6
    legs = [np.linspace(0, xr, 4000), np.linspace(xr, -xr, 8000)[1:]]
    x = np.concatenate(legs)
    t = np.arange(x.size) * 1.0
    f = g.simulate_friction(m, t, x)
    fr = f[3999]
    masing = fr - 2 * m.virgin_curve((xr - x[4000:]) / 2)
    np.testing.assert_allclose(f[4000:], masing, atol=1e-3 * m.stribeck.fs)


def test_passivity_of_a_closed_cycle_for_every_model():
    st_ = presets.paper_stribeck()
    models = [presets.paper_gms(), g.LuGre(st_, 1e6, 30.0, 3.0), g.MaxwellSlip([1e6, 1e4], [0.1, 0.05], 0.5), presets.paper_static_friction()]
    t = np.linspace(0, 2, 40001)
    for amp in (2e-8, 3e-6, 1e-3):
        x = amp * np.sin(2 * np.pi * t)
        for m in models:
            f = g.simulate_friction(m, t, x)
            half = t.size // 2
            work = np.sum(f[half + 1 :] * np.diff(x[half:]))
            assert work > 0, (type(m).__name__, amp, work)


def test_static_map_values():
    m = g.StaticFriction(g.Stribeck(1.0, 2.0, 0.01, 2.0), sigma=10.0)
    v = np.array([-0.02, 0.0, 0.01])
    expected = np.sign(v) * (1.0 + np.exp(-np.abs(v / 0.01) ** 2)) + 10.0 * v
    np.testing.assert_allclose(m.force(v), expected)


def test_paper_presets_follow_their_reading():
    st_lit = presets.paper_stribeck(presets.PaperReading.literal())
    assert st_lit.fs == 210.0 and st_lit.vs == pytest.approx(0.45)
    gms = presets.paper_gms()
    assert sum(gms.alpha) == pytest.approx(1.0)
    assert gms.k[0] == pytest.approx(3.2647059e6)
    # first block's pre-sliding range ~10 nm, as the paper implies
    assert gms.break_forces[0] / gms.k[0] == pytest.approx(0.0330 / 0.1058 * 0.21 / 3.2647059e6)
    gms_sum = presets.paper_gms(presets.PaperReading(gms_level="sum"))
    assert gms_sum.stribeck.fs == pytest.approx(0.1058)


def test_velocity_input_equals_position_input():
    m = presets.paper_gms()
    t = np.linspace(0, 1, 2001)
    v = 1e-4 * np.cos(2 * np.pi * 3 * t)
    x = np.concatenate(([0.0], np.cumsum(v[1:] * np.diff(t))))
    np.testing.assert_allclose(g.simulate_friction(m, t, velocity=v), g.simulate_friction(m, t, x))


def test_one_reading_of_table3_across_the_package():
    from gmsfric import glitch, identify

    assert identify.Table3Reading is presets.Table3Reading
    reading = presets.Table3Reading()
    assert glitch.PAPER_TABLE3 == {"static": reading.static, "gms": reading.gms}
    revised = glitch.table3_plant("static")
    assert (revised.a, revised.b, revised.c) == pytest.approx((0.01985, 2.40, 176.8))
    alt = presets.Table3Reading.static_unchanged()
    assert alt.static[1] == 168.40 and alt.gms[1] == 2.40
    with pytest.raises(g.InvalidInputError, match="`model`"):
        reading.plant("lugre")
