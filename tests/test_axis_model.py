"""The AxisModel: effects simulated in feedback, parameters by path, Monte Carlo, output choice."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

import gmsfric as g
from gmsfric import presets

DT = 1e-3


def coulomb_axis(**effects: object) -> g.AxisModel:
    friction = g.StaticFriction(g.Stribeck(5.0, 5.0, 1e-3), sigma=20.0)
    return g.AxisModel(g.Plant.from_mass(1.0), friction, g.Effects(**effects))  # type: ignore[arg-type]


def test_asymmetric_friction_sets_a_different_speed_per_direction() -> None:
    m = coulomb_axis(asymmetry=(1.5, 4.0))
    for push in (30.0, -30.0):
        res = m.simulate(DT, command=np.full(20_000, push))
        assert res.velocity is not None
        sign = np.sign(push)
        want = (abs(push) - (5.0 + sign * 1.5)) / (20.0 + sign * 4.0)
        assert abs(res.velocity[-1]) == pytest.approx(want, rel=1e-9)


def test_position_force_holds_the_axis_where_it_balances_the_push() -> None:
    # A spring g(q) = 200 N/m * q (Legendre P1 on [-0.1, 0.1]) against a 4 N push, viscous damping:
    # the axis settles at q = 4 / 200 = 20 mm (the Coulomb level is below the push).
    spring = g.PositionSeries.legendre(-0.1, 0.1, [0.0, 200.0 * 0.1])
    m = g.AxisModel(g.Plant.from_mass(1.0), g.StaticFriction(g.Stribeck(0.5, 0.5, 1e-3), sigma=30.0), g.Effects(position_force=spring))
    res = m.simulate(DT, command=np.full(20_000, 4.0))
    assert res.position is not None
    # The contact sticks as soon as the net force drops below the Coulomb level: anywhere
    # within +-0.5 N / 200 N/m of the balance.
    assert res.position[-1] == pytest.approx(0.02, abs=0.5 / 200 + 1e-9)
    np.testing.assert_allclose(spring(np.array([0.02])), [4.0])


@pytest.mark.parametrize(("beyond", "held"), [("linear", True), ("hold", False)])
def test_a_spring_fitted_over_a_short_travel_pushes_back_beyond_it_only_when_continued(beyond, held) -> None:
    # The same 200 N/m spring known over +-10 mm only; the 4 N push balances it at 20 mm.
    # Continued with its slope it still holds the axis there; held at its edge value (2 N)
    # it cannot, and the axis runs on.
    spring = g.PositionSeries.legendre(-0.01, 0.01, [0.0, 200.0 * 0.01], beyond=beyond)
    m = g.AxisModel(g.Plant.from_mass(1.0), g.StaticFriction(g.Stribeck(0.5, 0.5, 1e-3), sigma=30.0), g.Effects(position_force=spring))
    res = m.simulate(DT, command=np.full(20_000, 4.0))
    assert res.position is not None
    if held:
        assert res.position[-1] == pytest.approx(0.02, abs=0.5 / 200 + 1e-9)
        np.testing.assert_allclose(spring(np.array([0.02, -0.05])), [4.0, -10.0])
    else:
        assert res.position[-1] > 0.5
        np.testing.assert_allclose(spring(np.array([0.02, -0.05])), [2.0, -2.0])


def test_level_effects_need_a_static_map() -> None:
    with pytest.raises(g.InvalidInputError, match="static-map"):
        g.AxisModel(presets.paper_plant(), presets.paper_gms(), g.Effects(asymmetry=(0.1, 0.0)))


def test_parameters_round_trip_and_pickle() -> None:
    m = coulomb_axis(asymmetry=(1.0, 2.0), compliance=g.Compliance(0.3, 25.0, 0.2))
    p = m.parameters()
    assert p["plant.a"] == 1.0 and p["friction.stribeck.fc"] == 5.0 and p["effects.asymmetry.1"] == 2.0
    m2 = m.with_parameters({"friction.stribeck.fc": 6.0, "effects.compliance.mass": 0.4})
    assert m2.friction.stribeck.fc == 6.0 and m2.effects.compliance.mass == 0.4  # type: ignore[union-attr]
    assert m.parameters() == p, "the original is untouched"
    with pytest.raises(g.InvalidInputError, match="no parameter `plant.zz`"):
        m.with_parameters({"plant.zz": 1.0})
    with pytest.raises(g.InvalidInputError, match="`fs` must be >= 0"):
        m.with_parameters({"friction.stribeck.fs": -1.0})
    clone = pickle.loads(pickle.dumps(m2))
    assert clone == m2
    r1 = m2.simulate(DT, command=np.full(500, 20.0))
    r2 = clone.simulate(DT, command=np.full(500, 20.0))
    np.testing.assert_array_equal(r1.position, r2.position)


def test_covariance_samples_have_the_stated_spread() -> None:
    names = ("friction.stribeck.fc", "friction.sigma")
    cov = g.Covariance(names, np.diag([0.1**2, 0.5**2]))
    m = g.AxisModel(g.Plant.from_mass(1.0), g.StaticFriction(g.Stribeck(5.0, 5.0, 1e-3), sigma=20.0), covariance=cov)
    draws = m.sample(2000, seed=1)
    fc = np.array([d.friction.stribeck.fc for d in draws])  # type: ignore[union-attr]
    sig = np.array([d.friction.sigma for d in draws])  # type: ignore[union-attr]
    assert fc.mean() == pytest.approx(5.0, abs=4 * 0.1 / np.sqrt(2000))
    assert fc.std() == pytest.approx(0.1, rel=0.1)
    assert sig.std() == pytest.approx(0.5, rel=0.1)


def test_record_and_every_select_the_outputs() -> None:
    dt = 1e-4
    ref = 2e-4 * np.sin(2 * np.pi * 2.0 * np.arange(5001) * dt)
    full = g.simulate_closed_loop(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(), ref, dt)
    part = g.simulate_closed_loop(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(), ref, dt, record=("error", "friction"), every=10)
    assert part.position is None and part.command is None
    np.testing.assert_array_equal(part.error, full.error[::10])
    np.testing.assert_array_equal(part.friction, full.friction[::10])  # type: ignore[index]
    np.testing.assert_array_equal(part.t, full.t[::10])
    with pytest.raises(g.InvalidInputError, match="unknown output 'speed'"):
        g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), ref, dt, record=("speed",))
    with pytest.raises(g.InvalidInputError, match="unknown option"):
        g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), ref, dt, feed_forward=ref)  # type: ignore[call-arg]


def test_open_loop_needs_no_controller_and_matches_the_plant_response() -> None:
    plant = presets.paper_plant()
    u = np.sin(np.arange(3000) * 1e-3 * 2 * np.pi * 3.0)
    t, y = plant.simulate(u, 1e-3)
    res = g.simulate_closed_loop(plant, None, None, None, 1e-3, feedforward=u)
    np.testing.assert_array_equal(res.position, y)
    with pytest.raises(g.InvalidInputError, match="needs a `reference`"):
        g.simulate_closed_loop(plant, None, presets.paper_pid(), None, 1e-3, feedforward=u)


def test_the_presets_and_the_core_read_the_same_reference_numbers() -> None:
    from gmsfric import _gmsfric

    core = dict(_gmsfric.reference_values())
    st = presets.paper_stribeck()
    np.testing.assert_array_equal(core["paper_stribeck"], st.params)
    assert core["paper_sigma"] == [presets.paper_static_friction().sigma]
    gms = presets.paper_gms()
    np.testing.assert_allclose(core["paper_gms_k"], gms.k, rtol=1e-15)
    np.testing.assert_allclose(core["paper_gms_alpha"], gms.alpha, rtol=1e-15)
    assert core["paper_gms_c"] == [gms.c]
    np.testing.assert_allclose(core["paper_plant"], presets.paper_plant().params, rtol=1e-15)
    pid = presets.paper_pid()
    assert core["paper_pid"] == [pid.kp, pid.ki, pid.kd, pid.tf, pid.u_min, pid.u_max]
    np.testing.assert_allclose(core["emps_plant"], presets.emps_plant().params, rtol=1e-15)
    f = presets.emps_friction()
    assert core["emps_friction"] == [f.stribeck.fc, f.stribeck.fs, f.sigma, f.offset]
    c = presets.emps_controller()
    assert core["emps_controller"] == [c.kp, c.kv, c.u_min, c.u_max]
