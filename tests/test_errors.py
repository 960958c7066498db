"""Bad input raises an InvalidInputError (a ValueError) naming the argument, before any work."""

from __future__ import annotations

import numpy as np
import pytest

import gmsfric as g
from gmsfric import presets

ST = g.Stribeck(0.2, 0.3, 1e-3)
T = np.linspace(0, 1, 11)


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: g.GMS(ST, [1e5, -1e4], [0.5, 0.5], 1.0), "`k` must be > 0"),
        (lambda: g.GMS(ST, [1e5, 1e4], [0.5, 0.6], 1.0), "`alpha`.*must sum to 1"),
        (lambda: g.GMS(ST, [1e5], [0.5, 0.5], 1.0), "`alpha` has length 2 but `k` has length 1"),
        (lambda: g.GMS(ST, [], [], 1.0), "`k` is empty"),
        (lambda: g.GMS(ST, [1e5], [1.0], 0.0), "`c` must be > 0"),
        (lambda: g.GMS(ST, [1e5], [1.0], 1.0, slip_law="fast"), "`slip_law`"),
        (lambda: g.Stribeck(0.1, 0.2, vs=0.0), "`vs` must be > 0"),
        (lambda: g.Stribeck(-0.1, 0.2, 1e-3), "`fc` must be >= 0"),
        (lambda: g.Stribeck(float("nan"), 0.2, 1e-3), "`fc`.*must be finite"),
        (lambda: g.StaticFriction(ST, sigma=-1.0), "`sigma` must be >= 0"),
        (lambda: g.LuGre(ST, sigma0=-5.0), "`sigma0` must be > 0"),
        (lambda: g.MaxwellSlip([1e5, 1e4], [0.1]), "`w` has length 1"),
        (lambda: g.Plant(a=1.0, b=1.0, c=-3.0), "`c` must be >= 0"),
        (lambda: g.Plant.from_mass(-2.0), "`mass` must be > 0"),
        (lambda: g.Plant(1.0, 1.0, 1.0, delay=-1e-3), "`delay` must be >= 0"),
        (lambda: g.PID(1.0, u_min=1.0, u_max=-1.0), "`u_min`.*u_min < u_max"),
        (lambda: g.simulate_friction(presets.paper_gms(), T, np.zeros(5)), "`position` has length 5 but `t` has length 11"),
        (lambda: g.simulate_friction(presets.paper_gms(), T, np.r_[np.zeros(10), np.nan]), "`position` has a non-finite value .* at index 10"),
        (lambda: g.simulate_friction(presets.paper_gms(), T, np.r_[np.zeros(10), np.inf]), "`position` has a non-finite value"),
        (lambda: g.simulate_friction(presets.paper_gms(), np.r_[T[:5], T[3], T[6:]], np.zeros(11)), "`t` must be strictly increasing"),
        (lambda: g.simulate_friction(presets.paper_gms(), [], []), "`t` is empty"),
        (lambda: g.simulate_friction(presets.paper_gms(), T), "exactly one of `position` or `velocity`"),
        (lambda: g.simulate_friction("gms", T, T), "`model` must be a gmsfric friction model"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.zeros(10), 0.0), "`dt` must be > 0"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.zeros(10), -1e-3), "`dt` must be > 0"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.array([]), 1e-3), "`reference` is empty"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.zeros(10), 1e-3, feedforward=np.zeros(9)), "`feedforward` has length 9"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.zeros(10), 1e-3, load_force=np.full(10, np.nan)), "`load_force` has a non-finite value"),
        (lambda: g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), np.zeros(10), 1e-3, quantization=-1.0), "`quantization` must be >= 0"),
        (lambda: g.Plant(1.0, 1.0, 1.0).simulate(np.ones(3), dt=0), "`dt` must be > 0"),
        # numbers each finite whose combination overflows a double
        (lambda: g.PID(-7.4e285, 0.0, 1e200, 1e100).to_control(), "PID's transfer function \\(kp = -7.4e\\+285.*overflows a double"),
        (lambda: g.Plant(0.00084, 4.1e-18, 0.0, 9.99e225).to_control(pade_order=5), "Pade approximation \\(delay = 9.99e\\+225 s, order 5\\) overflows"),
        (lambda: g.Plant(1.6e-150, 9e-222, 0.0, 1e6, 2.79e247).mass, "force_gain / a = 2.79e\\+247 / 1.6e-150 overflows"),
        (lambda: g.model_io.model_from_dict({**g.AxisModel(presets.paper_plant(), presets.paper_gms()).model_document(), "provenance": np.array([])}),
         "\"provenance\" must be an object, got an array"),
        # finite measured signals whose squares overflow the fits' sums (a wrong unit or a corrupt log)
        (lambda: g.identify.estimate_frf(np.arange(256) * 1e-3, np.ones(256) * 1e200, np.ones(256)), "`input` reaches 1e\\+200.*check its unit"),
        (lambda: g.identify.fit_static_map(np.linspace(-1, 1, 20), np.full(20, 1e160)), "`force` reaches 1e\\+160"),
        (lambda: g.identify.fit_presliding(np.arange(100) * 1e-3, np.sin(np.arange(100)) * 1e150, np.ones(100)), "`position` reaches 1e\\+150"),
        (lambda: g.identify.fit_static_map(np.linspace(-1, 1, 20) * 1e-100, np.sign(np.linspace(-1, 1, 20))), "`velocity`: the fastest point is 1e-100"),
    ],
)
def test_bad_input_names_the_argument(call, match):
    with pytest.raises(g.InvalidInputError, match=match) as info:
        call()
    assert isinstance(info.value, ValueError) and isinstance(info.value, g.GmsfricError)


def test_core_errors_reach_python_as_the_same_classes():
    # Bypass the Python checks: the compiled core validates on its own and maps its typed errors.
    from gmsfric import _gmsfric

    with pytest.raises(g.InvalidInputError, match="`k` must be > 0"):
        _gmsfric.FrictionSpec.gms(0.1, 0.2, 1e-3, 1.0, [1.0, -1.0], [0.5, 0.5], 1.0, 0.0)
    spec = presets.paper_gms()._native
    with pytest.raises(g.InvalidInputError, match="`t` must be strictly increasing, but element 2"):
        _gmsfric.simulate_friction([spec], np.array([0.0, 1.0, 0.5]), np.zeros((1, 3)))
    with pytest.raises(g.InvalidInputError, match="`position` has a non-finite value"):
        _gmsfric.simulate_friction([spec], np.array([0.0, 1.0]), np.array([[0.0, np.nan]]))
    with pytest.raises(g.InvalidInputError, match="`dt` must be > 0"):
        _gmsfric.PlantSpec(1.0, 1.0, 1.0, 0.0, 1.0).discretize(-1.0)
    with pytest.raises(g.InvalidInputError, match="`c` must be >= 0"):
        _gmsfric.PlantSpec(1.0, 1.0, -1.0, 0.0, 1.0)
