"""python-control interop: the exported loop has the margins of gmsfric's own responses."""

from __future__ import annotations

import numpy as np
import pytest

import gmsfric as g
from gmsfric import presets

control = pytest.importorskip("control")


def test_continuous_export_refuses_to_drop_the_delay() -> None:
    plant = presets.paper_plant()
    with pytest.raises(g.InvalidInputError, match="delay"):
        plant.to_control()
    assert control.dcgain(g.Plant(2.0, 3.0, 4.0).to_control()) == pytest.approx(0.5)
    with pytest.raises(g.InvalidInputError, match="Pade"):
        g.Plant(1.0, 1.0, 1.0, delay=1e-13).to_control(pade_order=3)
    # A Pade approximation keeps the phase of the delay at low frequency.
    tf = plant.to_control(pade_order=4)
    w = 2 * np.pi * 20.0
    np.testing.assert_allclose(np.angle(tf(1j * w)), np.angle(plant.frequency_response([20.0])[0]), atol=1e-4)


def test_discrete_export_has_the_delay_and_matches_the_sampled_response() -> None:
    plant, dt = presets.paper_plant(), 1e-4
    tf = plant.to_control(dt=dt)
    f = np.array([1.0, 10.0, 100.0, 1000.0])
    z = np.exp(2j * np.pi * f * dt)
    np.testing.assert_allclose(tf(z), plant.frequency_response(f, dt=dt), rtol=1e-9)
    # Phase at 100 Hz: the rational part gives -165 deg, the 1.29 ms delay another -46.4 deg;
    # the sampled plant adds half a sample of hold.
    rational = np.degrees(np.angle(g.Plant(plant.a, plant.b, plant.c).frequency_response([100.0])[0]))
    assert rational == pytest.approx(-165.0, abs=0.5)
    cont = rational - 360 * 100.0 * plant.delay
    disc = np.degrees(np.unwrap([0.0, np.angle(tf(np.exp(2j * np.pi * 100.0 * dt)))]))[1]
    assert (disc - (cont - 360 * 100.0 * dt / 2) + 180) % 360 - 180 == pytest.approx(0.0, abs=0.5)
    # The discrete step response equals the core's open-loop simulation.
    u = np.ones(400)
    _, y = plant.simulate(u, dt)
    _, y_ctrl = control.forced_response(tf, T=np.arange(400) * dt, U=u)
    np.testing.assert_allclose(y_ctrl, y, rtol=1e-8, atol=1e-15)


def test_loop_margins_match_gmsfric_frequency_responses() -> None:
    plant, pid, dt = presets.paper_plant(), presets.paper_pid(), 1e-4
    loop = pid.to_control(dt=dt) * plant.to_control(dt=dt)
    gm, pm, wcg, wcp = control.margin(loop)
    # gmsfric's own loop response at the crossover the export reports.
    f_c = wcp / (2 * np.pi)
    L = pid.frequency_response([f_c], dt) * plant.frequency_response([f_c], dt=dt)
    assert abs(L[0]) == pytest.approx(1.0, rel=1e-6)
    assert 180 + np.degrees(np.angle(L[0])) == pytest.approx(pm, abs=1e-4)
    # Find the crossover independently on a fine grid of gmsfric's response.
    f = np.geomspace(1.0, 1000.0, 200_001)
    Lf = pid.frequency_response(f, dt) * plant.frequency_response(f, dt=dt)
    i = np.argmin(np.abs(np.abs(Lf) - 1.0))
    assert f[i] == pytest.approx(f_c, rel=1e-3)


def test_pid_export_matches_the_core_controller() -> None:
    pid, dt = g.PID(3.0, 20.0, 0.05, tf=2e-3), 1e-3
    e = np.sin(np.arange(200) * 0.07)
    # The core's controller in open loop: drive a plant that ignores its input? Use the identity:
    # u = C(z) e on the error sequence, simulated by python-control, against the formula.
    _, u_ctrl = control.forced_response(pid.to_control(dt=dt), T=np.arange(200) * dt, U=e)
    integral, d, prev, u = 0.0, 0.0, e[0], []
    for ek in e:
        d = (pid.tf * d + pid.kd * (ek - prev)) / (pid.tf + dt)
        integral += pid.ki * dt * ek
        u.append(pid.kp * ek + integral + d)
        prev = ek
    np.testing.assert_allclose(u_ctrl, u, rtol=1e-9, atol=1e-12)


def test_from_control_round_trip() -> None:
    p = g.Plant(0.02, 150.0, 80.0, delay=1e-3, force_gain=35.0)
    back = g.Plant.from_control(2.0 * p.to_control(pade_order=None) if p.delay == 0 else control.tf([0.04], [2.0, 300.0, 160.0]), delay=1e-3, force_gain=35.0)
    assert back == p
    with pytest.raises(g.InvalidInputError, match="a / \\(s\\^2"):
        g.Plant.from_control(control.tf([1.0, 1.0], [1.0, 2.0, 3.0]))
