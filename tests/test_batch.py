"""Batch simulation: equals individual runs (exactly, or to rounding for runs in SIMD lanes),
stacked shapes, errors name the run."""

from __future__ import annotations

import io

import numpy as np
import pytest

from gmsfric import GMS, PID, InvalidInputError, LuGre, Plant, SimulationError, StaticFriction, Stribeck, simulate_closed_loop, simulate_friction
from gmsfric._progress import Progress
from gmsfric.batch import BatchResult, grid, simulate_batch, simulate_friction_batch, sweep

DT = 1e-4
N = 2000


@pytest.fixture(scope="module")
def axis():
    st = Stribeck(0.1826, 0.210, 0.45e-3, 1.0)
    w = np.array([0.0330, 0.0570, 0.0132, 0.0026])
    gms = GMS(st, [3264.7059e3, 8.8941e3, 23.7869e3, 2.6131e3], w / w.sum(), 1 / 0.45e-3, 6.9846)
    plant = Plant(0.01985, 168.4, 176.8, 1.29e-3, 1.0)
    pid = PID(5.0e5, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0)
    ref = 2e-4 * np.sin(2 * np.pi * 2.0 * np.arange(N) * DT)
    return plant, gms, pid, ref


FIELDS = ("position", "velocity", "measured", "command", "friction")


@pytest.mark.parametrize("threads", [None, 1, 2])
def test_batch_equals_individual_runs_exactly(axis, threads):
    plant, gms, pid, ref = axis
    st = gms.stribeck
    frictions = [gms, None, StaticFriction(st, 6.98), LuGre(st, 1e5, 300.0, 6.98)]
    controllers = [PID(kp, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0) for kp in (3e5, 5e5, 7e5, 9e5)]
    load = np.linspace(0.0, 0.05, N)
    res = simulate_batch(plant, frictions, controllers, ref, DT, load_force=load, drive_limit=8.0, threads=threads)
    assert isinstance(res, BatchResult) and len(res) == 4
    for name in FIELDS:
        assert getattr(res, name).shape == (4, N)
    assert res.reference.shape == (4, N) and res.t.shape == (N,)
    for i, (f, c) in enumerate(zip(frictions, controllers)):
        single = simulate_closed_loop(plant, f, c, ref, DT, load_force=load, drive_limit=8.0)
        for name in FIELDS:
            np.testing.assert_array_equal(getattr(res, name)[i], getattr(single, name), err_msg=f"run {i} {name}")
        np.testing.assert_array_equal(res[i].error, single.error)
    assert not np.array_equal(res.position[0], res.position[1])


def test_per_run_reference_and_inputs(axis):
    plant, gms, pid, ref = axis
    refs = np.stack([ref, 0.5 * ref, -ref])
    noise = np.random.default_rng(1).normal(0, 1e-7, (3, N))
    res = simulate_batch([plant] * 3, gms, pid, refs, DT, measurement_noise=noise)
    for i in range(3):
        single = simulate_closed_loop(plant, gms, pid, refs[i], DT, measurement_noise=noise[i])
        np.testing.assert_array_equal(res.position[i], single.position)
        np.testing.assert_array_equal(res.reference[i], refs[i])


def test_sweep_grid_and_assignments(axis):
    plant, gms, pid, ref = axis
    combos, res = sweep(plant, gms, pid, ref, DT, vary={"controller.kp": [3e5, 6e5], "friction.stribeck.fc": [0.15, 0.19], "plant.delay": [1e-3]})
    assert len(combos) == 4 and res.position.shape == (4, N)
    assert combos[3] == {"controller.kp": 6e5, "friction.stribeck.fc": 0.19, "plant.delay": 1e-3}
    from dataclasses import replace

    g = replace(gms, stribeck=replace(gms.stribeck, fc=0.19))
    single = simulate_closed_loop(replace(plant, delay=1e-3), g, replace(pid, kp=6e5), ref, DT)
    # Four runs of one structure share a SIMD vector: equal to the single run to rounding.
    np.testing.assert_allclose(res.position[3], single.position, rtol=0, atol=1e-12 * np.abs(single.position).max())
    assert grid(a=[1, 2], b="xy") == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 2, "b": "x"}, {"a": 2, "b": "y"}]
    # Monte Carlo style: a list of assignments, one per run.
    combos, res = sweep(plant, gms, pid, ref, DT, vary=[{"friction.c": c} for c in (1000.0, 3000.0, 5000.0)])
    assert res.position.shape == (3, N)
    with pytest.raises(InvalidInputError, match="no parameter `kq`"):
        sweep(plant, gms, pid, ref, DT, vary={"controller.kq": [1.0]})
    with pytest.raises(InvalidInputError, match="must start with"):
        sweep(plant, gms, pid, ref, DT, vary={"kp": [1.0]})


def test_errors_name_the_failing_run(axis):
    plant, gms, pid, ref = axis
    unstable = PID(1e12, 0.0, 0.0)
    with pytest.raises(SimulationError, match=r"run 2 \(of 4\)"):
        simulate_batch(plant, gms, [pid, pid, unstable, unstable], ref, DT)
    with pytest.raises(InvalidInputError, match="rows but there are 3 runs"):
        simulate_batch([plant] * 3, gms, pid, np.zeros((2, N)), DT)
    bad = np.tile(ref, (3, 1))
    bad[1, 7] = np.nan
    with pytest.raises(InvalidInputError, match="row 1, index 7"):
        simulate_batch([plant] * 3, gms, pid, bad, DT)
    with pytest.raises(InvalidInputError, match="different numbers of runs"):
        simulate_batch([plant] * 3, [gms] * 2, pid, ref, DT)
    with pytest.raises(InvalidInputError, match="threads"):
        simulate_batch(plant, gms, pid, ref, DT, threads=0)
    with pytest.raises(InvalidInputError, match="load_force"):
        simulate_batch(plant, gms, pid, ref, DT, load_force=np.zeros(N + 1))
    with pytest.raises(InvalidInputError, match=r"frictions\[1\]"):
        simulate_batch(plant, [gms, "gms"], pid, ref, DT)


def test_binding_error_carries_run_index(axis):
    from gmsfric import _gmsfric

    plant, gms, pid, ref = axis
    axis_spec = _gmsfric.AxisSpec(plant._native, gms._native)
    inputs = {"reference": np.stack([ref, ref]), "feedforward": None, "input_disturbance": None, "load_force": None, "measurement_noise": None,
              "quantization": 0.0, "drive_min": -np.inf, "drive_max": np.inf, "initial_position": None, "initial_velocity": 0.0}
    with pytest.raises(InvalidInputError, match=r"run 0 \(of 2\) failed: .*dt"):
        # The binding re-validates what the Python layer would have caught.
        _gmsfric.simulate([axis_spec] * 2, [pid._native] * 2, -DT, inputs, ["position"])


def test_progress_reports_to_stderr(axis, monkeypatch):
    plant, gms, pid, ref = axis
    stream = io.StringIO()
    import gmsfric.batch as batch_mod

    # a StringIO is not a terminal: progress is drawn there only when forced
    monkeypatch.setattr(batch_mod, "Progress", lambda label, total: Progress(label, total=total, stream=stream, force=True, every=0.0))
    simulate_batch([plant] * 3, gms, pid, ref, DT, progress=True)
    assert "batch runs" in stream.getvalue() and "3/3" in stream.getvalue()


def test_friction_batch_equals_single_runs_and_shares_input(axis):
    _, gms, _, _ = axis
    t = np.arange(5000) * DT
    x = 1e-5 * np.sin(2 * np.pi * 3 * t)
    models = [gms, StaticFriction(gms.stribeck, 6.98), LuGre(gms.stribeck, 1e5, 300.0)]
    f = simulate_friction_batch(models, t, x, threads=2)
    assert f.shape == (3, t.size)
    for i, m in enumerate(models):
        np.testing.assert_array_equal(f[i], simulate_friction(m, t, x))
    rows = np.stack([x, 2 * x, 3 * x])
    f2 = simulate_friction_batch([gms] * 3, t, rows)
    np.testing.assert_array_equal(f2[2], simulate_friction(gms, t, 3 * x))
    bad = rows.copy()
    bad[2, 3] = np.inf
    with pytest.raises(InvalidInputError, match="row 2, index 3"):
        simulate_friction_batch([gms] * 3, t, bad)


@pytest.mark.parametrize("n_runs", [8, 17])
def test_runs_in_simd_lanes_agree_with_single_runs_and_not_with_threads(axis, n_runs):
    plant, gms, pid, ref = axis
    from dataclasses import replace

    st = gms.stribeck
    frictions = [replace(gms, stribeck=replace(st, fc=st.fc * x, fs=st.fs * x)) for x in np.linspace(0.5, 1.5, n_runs)]
    one = simulate_batch(plant, frictions, pid, ref, DT, threads=1, record=("position", "friction", "error"))
    two = simulate_batch(plant, frictions, pid, ref, DT, threads=2, record=("position", "friction", "error"))
    for name in ("position", "friction", "recorded_error"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name), err_msg=name)
    for i, f in enumerate(frictions):
        single = simulate_closed_loop(plant, f, pid, ref, DT)
        np.testing.assert_allclose(one.position[i], single.position, rtol=0, atol=1e-12 * np.abs(single.position).max())
        np.testing.assert_allclose(one.friction[i], single.friction, rtol=0, atol=1e-10 * np.abs(single.friction).max())
        np.testing.assert_allclose(one.error[i], single.error, rtol=0, atol=1e-12 * np.abs(single.position).max())


_LANES_SCRIPT = """
import sys, numpy as np
from gmsfric import GMS, PID, Plant, Stribeck
from gmsfric.batch import simulate_batch
st = Stribeck(0.1826, 0.210, 0.45e-3, 1.0)
w = np.array([0.0330, 0.0570, 0.0132, 0.0026])
frictions = [GMS(Stribeck(0.1826 * x, 0.210 * x, 0.45e-3, 1.0), [3264.7059e3, 8.8941e3, 23.7869e3, 2.6131e3], w / w.sum(), 1 / 0.45e-3, 6.9846)
             for x in np.linspace(0.5, 1.5, 8)]
ref = 2e-4 * np.sin(2 * np.pi * 2.0 * np.arange(4000) * 1e-4)
res = simulate_batch(Plant(0.01985, 168.4, 176.8, 1.29e-3, 1.0), frictions, PID(5.0e5, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0), ref, 1e-4,
                     threads=1, record=("position", "friction"))
np.save(sys.argv[1], np.stack([res.position, res.friction]))
"""


@pytest.mark.parametrize("disabled", ["GMSFRIC_NO_AVX512", "GMSFRIC_NO_AVX2"])
def test_every_instruction_set_path_of_the_lanes_gives_the_same_runs(tmp_path, disabled):
    """The batch kernel is compiled for AVX-512, AVX2 + FMA and baseline x86-64; the CPU picks one.
    Turning the wider paths off (in a fresh process: the choice is made once) changes only
    rounding: without FMA every multiply-add rounds twice."""
    import os
    import subprocess
    import sys

    paths = {}
    for name, env in (("default", {}), (disabled, {disabled: "1"})):
        out = tmp_path / f"{name}.npy"
        subprocess.run([sys.executable, "-c", _LANES_SCRIPT, str(out)], check=True, timeout=120, env={**os.environ, **env})
        paths[name] = np.load(out)
    a, b = paths["default"], paths[disabled]
    for k, what in enumerate(("position", "friction")):
        scale = np.abs(a[k]).max()
        assert scale > 0
        np.testing.assert_allclose(b[k], a[k], rtol=0, atol=(1e-12 if k == 0 else 1e-10) * scale, err_msg=what)
