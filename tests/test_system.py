"""Plant, delay and closed loop through the Python API."""

from __future__ import annotations

import numpy as np
import pytest

import gmsfric as g
from gmsfric import presets


def test_open_loop_matches_frequency_response_and_delay():
    p = g.Plant(a=50.0, b=40.0, c=900.0, delay=1.29e-3)
    dt = 1e-4
    f = 7.0
    n = 40000
    u = np.sin(2 * np.pi * f * (np.arange(n) + 0.5) * dt)
    t, y = p.simulate(u, dt)
    h = p.frequency_response([f])[0]
    expected = np.abs(h) * np.sin(2 * np.pi * f * t + np.angle(h))
    tail = slice(n - 5000, n)
    np.testing.assert_allclose(y[tail], expected[tail], atol=2e-3 * np.abs(h))


def test_closed_loop_result_unpacks_and_plots(tmp_path):
    dt = 1e-4
    r = 1e-3 * np.sin(2 * np.pi * 0.5 * np.arange(0, 2, dt))
    res = g.simulate_closed_loop(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(), r, dt)
    t, y = res
    assert t.shape == y.shape == r.shape
    np.testing.assert_allclose(res.error, r - res.position)
    assert np.max(np.abs(res.error[5000:])) < 1e-4
    fig = res.plot()
    fig.savefig(tmp_path / "cl.png")
    assert (tmp_path / "cl.png").stat().st_size > 1000


@pytest.mark.parametrize("every", [1, 7])
def test_time_axis_of_a_result_is_the_recorded_steps_times_dt(every):
    # Built on first use: one output recorded, the same k dt as every decimated sample.
    dt = 2.5e-4
    r = 1e-3 * np.sin(2 * np.pi * 0.5 * np.arange(1001) * dt)
    res = g.simulate_closed_loop(presets.paper_plant(), presets.paper_gms(), presets.paper_pid(), r, dt, record=("error",), every=every)
    steps = np.arange(0, r.size, every)
    assert res.error.shape == res.t.shape == steps.shape
    np.testing.assert_array_equal(res.t, steps * dt)
    batch = g.batch.simulate_batch(presets.paper_plant(), [presets.paper_gms()] * 2, presets.paper_pid(), r, dt, record=("error",), every=every)
    np.testing.assert_array_equal(batch[1].t, batch.t)
    np.testing.assert_array_equal(batch.t, steps * dt)


def test_emps_reference_model_holds_still_under_offset_free_zero_reference():
    # EMPS cascade with the reference friction and a constant reference: the axis settles and
    # friction balances the command exactly (stiction is held without chattering).
    dt = 1e-3
    r = np.full(3000, 0.1)
    res = g.simulate_closed_loop(presets.emps_plant(), presets.emps_friction(), presets.emps_controller(), r, dt, initial_position=0.099)
    assert np.ptp(res.position[-500:]) < 1e-9
    np.testing.assert_allclose(res.friction[-500:], presets.EMPS_GTAU * res.command[-500:], rtol=1e-9, atol=1e-9)


def test_quantization_and_noise_reach_the_controller():
    dt = 1e-3
    r = np.linspace(0, 1e-3, 500)
    q = 1e-5
    res = g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), r, dt, quantization=q)
    np.testing.assert_allclose(res.measured / q, np.round(res.measured / q), atol=1e-9)
    noise = np.random.default_rng(0).normal(0, 1e-6, r.size)
    res2 = g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), r, dt, measurement_noise=noise)
    np.testing.assert_allclose(res2.measured - res2.position, noise)


def test_drive_limit_saturates_command():
    dt = 1e-3
    r = np.full(200, 0.05)
    res = g.simulate_closed_loop(presets.paper_plant(), None, presets.paper_pid(), r, dt, drive_limit=3.0, initial_position=0.0)
    assert np.max(np.abs(res.command)) == pytest.approx(3.0)


def test_divergence_is_an_exception_not_nan():
    dt = 1e-3
    r = np.ones(20000)
    unstable = g.PID(kp=1e9, ki=0, kd=0)
    with pytest.raises(g.SimulationError, match=r"non-finite \w+ at step \d+"):
        g.simulate_closed_loop(g.Plant(1.0, 0.0, 0.0, delay=5e-3), None, unstable, r, dt, initial_position=0.0)
