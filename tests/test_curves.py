"""The numpy friction curves: physics properties, and agreement with the models and the core."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import gmsfric as g
from gmsfric import curves, presets

pos = st.floats(min_value=1e-6, max_value=1e3)


@given(fc=pos, fs=pos, vs=st.floats(min_value=1e-6, max_value=1.0), delta=st.floats(min_value=0.2, max_value=5.0), sigma=st.floats(min_value=0, max_value=1e3))
def test_static_map_is_odd_bounded_by_its_levels_and_zero_at_rest(fc, fs, vs, delta, sigma):
    v = np.geomspace(1e-9, 10.0, 200)
    f = curves.static_map(v, fc, fs, vs, delta, sigma)
    np.testing.assert_array_equal(curves.static_map(-v, fc, fs, vs, delta, sigma), -f)
    s = curves.stribeck(v, fc, fs, vs, delta)
    tol = 1e-12 * max(fc, fs)
    assert np.all(s >= min(fc, fs) - tol) and np.all(s <= max(fc, fs) + tol)
    assert np.all(np.diff(s) * np.sign(fc - fs) >= -tol)  # monotone from fs at rest towards fc
    assert curves.static_map(0.0, fc, fs, vs, delta, sigma, offset=0.25) == 0.25
    assert abs(curves.stribeck(0.0, fc, fs, vs, delta) - fs) <= tol


def test_static_map_matches_the_core_including_offset_and_linear_region():
    gms = presets.paper_gms()
    st_ = gms.stribeck
    model = g.StaticFriction(st_, 6.98, offset=-0.3, v_linear=1e-4)
    v = np.linspace(-1e-3, 1e-3, 2001)
    ours = curves.static_map(v, st_.fc, st_.fs, st_.vs, st_.delta, 6.98, offset=-0.3, v_linear=1e-4)
    np.testing.assert_allclose(ours, model.force(v), rtol=1e-12, atol=1e-15)


@given(k=st.lists(st.floats(min_value=1.0, max_value=1e8), min_size=1, max_size=5), data=st.data())
def test_virgin_curve_starts_at_the_total_stiffness_and_saturates_at_the_total_break_force(k, data):
    w = data.draw(st.lists(st.floats(min_value=1e-6, max_value=10.0), min_size=len(k), max_size=len(k)))
    d_min = min(wi / ki for ki, wi in zip(k, w))
    d_max = max(wi / ki for ki, wi in zip(k, w))
    x = np.array([d_min / 2, 2 * d_max, -2 * d_max])
    f = curves.virgin_curve(x, k, w)
    assert abs(f[0] - sum(k) * d_min / 2) <= 1e-9 * abs(f[0])
    assert abs(f[1] - sum(w)) <= 1e-12 * sum(w) and f[2] == -f[1]


def test_virgin_curve_is_the_models_one():
    gms = presets.paper_gms()
    x = np.linspace(-5e-5, 5e-5, 501)
    np.testing.assert_array_equal(curves.virgin_curve(x, gms.k, gms.break_forces), gms.virgin_curve(x))
    ms = g.MaxwellSlip([3e6, 9e3], [0.03, 0.06])
    np.testing.assert_array_equal(curves.virgin_curve(x, ms.k, ms.w), ms.virgin_curve(x))
