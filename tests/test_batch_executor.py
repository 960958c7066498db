"""Batches on an executor (a thread pool, a Dask cluster): chunks of whole SIMD groups give the
local run's results exactly, in order; models and options travel by pickle."""

from __future__ import annotations

import dataclasses
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from gmsfric import GMS, PID, InvalidInputError, Plant, SimulationError, Stribeck
from gmsfric.batch import simulate_batch

DT = 1e-4
N = 3000


@pytest.fixture(scope="module")
def sweep_runs():
    st = Stribeck(0.1826, 0.210, 0.45e-3, 1.0)
    w = np.array([0.0330, 0.0570, 0.0132, 0.0026])
    gms = GMS(st, [3264.7059e3, 8.8941e3, 23.7869e3, 2.6131e3], w / w.sum(), 1 / 0.45e-3, 6.9846)
    plant = Plant(0.01985, 168.4, 176.8, 1.29e-3, 1.0)
    # 19 runs: friction levels and gains (two whole SIMD groups of LANES = 8, then 3 runs alone),
    # one frictionless run in the second group (that group runs one by one).
    frictions = [dataclasses.replace(gms, stribeck=dataclasses.replace(st, fc=st.fc * x, fs=st.fs * x)) for x in np.linspace(0.5, 1.5, 19)]
    frictions[10] = None
    controllers = [PID(kp, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0) for kp in np.linspace(3e5, 8e5, 19)]
    ref = 2e-4 * np.sin(2 * np.pi * 2.0 * np.arange(N) * DT)
    return plant, frictions, controllers, ref


def assert_same_results(a, b):
    for name in ("position", "command", "friction", "recorded_error"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)


@pytest.mark.parametrize("chunk_size", [None, 3, 4, 8])
def test_thread_pool_chunks_equal_the_local_batch(sweep_runs, chunk_size):
    plant, frictions, controllers, ref = sweep_runs
    options = {"record": ("position", "command", "friction", "error")}
    local = simulate_batch(plant, frictions, controllers, ref, DT, **options)
    with ThreadPoolExecutor(2) as pool:
        remote = simulate_batch(plant, frictions, controllers, ref, DT, executor=pool, chunk_size=chunk_size, threads=1, **options)
    assert_same_results(local, remote)
    assert remote.position.shape == (19, N)
    # Per-run 2-D inputs are split with the runs.
    noise = np.random.default_rng(2).normal(0.0, 1e-8, (19, N))
    local = simulate_batch(plant, frictions, controllers, ref, DT, measurement_noise=noise)
    with ThreadPoolExecutor(2) as pool:
        remote = simulate_batch(plant, frictions, controllers, ref, DT, measurement_noise=noise, executor=pool, chunk_size=4)
    assert_same_results(local, remote)


def test_executor_errors_name_the_chunk_and_bad_executor_is_refused(sweep_runs):
    plant, frictions, controllers, ref = sweep_runs
    unstable = list(controllers)
    unstable[9] = PID(5e11, 0.0, 0.0)  # diverges (non-finite command)
    with ThreadPoolExecutor(2) as pool, pytest.raises(SimulationError, match=r"runs 8\.\.15"):
        simulate_batch(plant, frictions, unstable, ref, DT, executor=pool, chunk_size=4)
    with pytest.raises(InvalidInputError, match="executor"):
        simulate_batch(plant, frictions, controllers, ref, DT, executor=object())
    with pytest.raises(InvalidInputError, match="chunk_size"):
        simulate_batch(plant, frictions, controllers, ref, DT, executor=ThreadPoolExecutor(1), chunk_size=0)


@pytest.mark.slow
def test_dask_local_cluster_gives_the_local_results_in_order(sweep_runs):
    distributed = pytest.importorskip("distributed")
    plant, frictions, controllers, ref = sweep_runs
    local = simulate_batch(plant, frictions, controllers, ref, DT, record=("position", "friction", "error"))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = simulate_batch(plant, frictions, controllers, ref, DT, record=("position", "friction", "error"), executor=client.get_executor(), chunk_size=4, threads=1)
    assert_same_results(local, remote)
