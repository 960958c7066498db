"""Long simulations release the GIL (another Python thread keeps running), and friction-only
simulation reads contiguous float64 input without copying it."""

from __future__ import annotations

import threading
import time

import numpy as np

import gmsfric.models as models_mod
from gmsfric import GMS, PID, Plant, Stribeck, simulate_closed_loop, simulate_friction
from gmsfric._validate import as_array
from gmsfric.batch import _rows, simulate_batch

DT = 1e-4


def _axis():
    st = Stribeck(0.1826, 0.210, 0.45e-3, 1.0)
    gms = GMS(st, [3.26e6, 8.9e3, 2.4e4, 2.6e3], [0.31, 0.54, 0.125, 0.025], 1 / 0.45e-3, 6.98)
    return Plant(0.01985, 168.4, 176.8, 1.29e-3, 1.0), gms, PID(5.0e5, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0)


def _main_thread_runs_during(call) -> int:
    """Run `call` in a thread; return how often the main thread executed Python in the middle
    half of the call (0 if the call held the GIL throughout)."""
    span: list[float] = []

    def worker() -> None:
        span.append(time.perf_counter())
        call()
        span.append(time.perf_counter())

    stamps: list[float] = []
    th = threading.Thread(target=worker)
    th.start()
    count = 0
    while th.is_alive():
        count += 1
        if count % 1000 == 0:
            stamps.append(time.perf_counter())
    th.join()
    t0, t1 = span
    lo, hi = t0 + 0.25 * (t1 - t0), t1 - 0.25 * (t1 - t0)
    return sum(1 for s in stamps if lo <= s <= hi)


def test_closed_loop_releases_gil():
    plant, gms, pid = _axis()
    ref = 2e-4 * np.sin(2 * np.pi * np.arange(3_000_000) * DT)
    # With the GIL held for the whole call the main thread could not run at all in its middle.
    assert _main_thread_runs_during(lambda: simulate_closed_loop(plant, gms, pid, ref, DT)) >= 2


def test_batch_releases_gil():
    plant, gms, pid = _axis()
    ref = 2e-4 * np.sin(2 * np.pi * np.arange(1_000_000) * DT)
    assert _main_thread_runs_during(lambda: simulate_batch([plant] * 4, gms, pid, ref, DT, threads=1, progress=False)) >= 2


def test_friction_only_input_is_not_copied(monkeypatch):
    x = np.sin(np.linspace(0.0, 10.0, 100_000)) * 1e-5
    t = np.arange(x.size) * 1e-3
    assert as_array("position", x) is x
    assert np.shares_memory(_rows("position", x, 3, x.size, allow_2d=True), x)
    seen: dict[str, np.ndarray] = {}
    real = models_mod.as_array

    def spy(name, values, **kw):
        out = real(name, values, **kw)
        seen[name] = out
        return out

    monkeypatch.setattr(models_mod, "as_array", spy)
    _, gms, _ = _axis()
    f = simulate_friction(gms, t, x)
    assert f.shape == x.shape
    assert seen["position"] is x and seen["t"] is t
    # A strided view must be made contiguous (a copy), still giving the same forces.
    xs = np.repeat(x, 2)[::2]
    assert not xs.flags.c_contiguous
    np.testing.assert_array_equal(simulate_friction(gms, t, xs), f)
