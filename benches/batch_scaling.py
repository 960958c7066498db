"""Batch throughput: runs in SIMD lanes on one core, then on every core (one process).

    python benches/batch_scaling.py [--runs 16] [--steps 1000000] [--repeats 3]

The batch is the issue's sweep on the ``numba_baseline.py`` system (paper axis, 4-block GMS, PID
5e5 / 2.5e6 / 1e3, 10 mm / 0.01 Hz sine): friction levels x0.5 to x1.5, one per run, each run
recording its tracking error. Rows, interleaved repetitions (so load changes hit all of them):

- one run at a time: ``simulate_closed_loop`` in a Python loop (the latency-optimised single run);
- ``simulate_batch(..., threads=1)``: runs of one structure go in groups of 8 per SIMD vector
  group (one AVX-512 register, or two AVX2 registers);
- ``simulate_batch(..., threads=k)`` for every core;
- with ``--dask``: ``simulate_batch(..., executor=client.get_executor())`` on a
  ``dask.distributed.LocalCluster`` (one worker process per core, one thread each), chunks of
  ``--chunk`` runs: the cost of shipping models and results on this machine (a real cluster adds
  machines).

Prints min / median steps/s (wall and process CPU time) and the ratio to one run at a time, and
checks that the batch agrees with the single runs (lanes: to rounding, see BENCHMARKS.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from gmsfric import simulate_closed_loop
from gmsfric.batch import simulate_batch

sys.path.insert(0, str(Path(__file__).resolve().parent))
import numba_baseline as nb  # noqa: E402  (same directory: the headline system)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--steps", type=int, default=1_000_000)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--dask", action="store_true", help="add a dask LocalCluster row (needs the dask extra)")
    ap.add_argument("--chunk", type=int, default=8, help="runs per executor chunk with --dask (whole lane groups)")
    args = ap.parse_args()
    plant, gms, pid = nb.gmsfric_system(4)
    ref = nb.reference(args.steps)
    levels = np.linspace(0.5, 1.5, args.runs)
    st = gms.stribeck
    frictions = [dataclasses.replace(gms, stribeck=dataclasses.replace(st, fc=st.fc * x, fs=st.fs * x)) for x in levels]
    total = args.runs * args.steps
    load = os.getloadavg()
    print(f"# {args.runs} runs x {args.steps:.0e} steps, {os.cpu_count()} logical CPUs, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")

    def singles() -> list[np.ndarray]:
        return [simulate_closed_loop(plant, f, pid, ref, nb.DT, record=("error",)).error for f in frictions]

    def batch(threads: int) -> np.ndarray:
        return simulate_batch(plant, frictions, pid, ref, nb.DT, threads=threads, progress=False, record=("error",)).error

    rows = {"one run at a time (simulate_closed_loop loop)": singles}
    for k in range(1, (os.cpu_count() or 1) + 1):
        rows[f"simulate_batch, threads={k}"] = lambda k=k: batch(k)
    client = None
    if args.dask:
        from distributed import Client, LocalCluster

        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
        ex = client.get_executor()
        rows[f"dask LocalCluster ({os.cpu_count()} workers x 1 thread), chunks of {args.chunk}"] = lambda: simulate_batch(
            plant, frictions, pid, ref, nb.DT, threads=1, progress=False, record=("error",), executor=ex, chunk_size=args.chunk).error
    wall: dict[str, list[float]] = {k: [] for k in rows}
    cpu: dict[str, list[float]] = {k: [] for k in rows}
    outs: dict[str, object] = {}
    for rep in range(args.repeats):
        names = list(rows)
        names = names[rep % len(names):] + names[: rep % len(names)]
        for name in names:
            c0, w0 = time.process_time(), time.perf_counter()
            out = rows[name]()
            wall[name].append(time.perf_counter() - w0)
            cpu[name].append(time.process_time() - c0)
            if rep == 0:
                outs[name] = out
    base = next(iter(rows))
    print("\n(cpu: this process's CPU time; the dask workers are other processes, read its wall column)")
    print("\n| how | wall steps/s min / median | cpu steps/s min / median | x one run at a time (wall, median) |")
    print("|---|---|---|---|")
    for name in rows:
        rw = [total / t for t in wall[name]]
        rc = [total / t for t in cpu[name]]
        ratio = statistics.median(b / a for a, b in zip(wall[name], wall[base]))
        print(f"| {name} | {min(rw):.3e} / {statistics.median(rw):.3e} | {min(rc):.3e} / {statistics.median(rc):.3e} | {ratio:.2f} |")
    single = np.stack(outs[base])  # type: ignore[arg-type]
    scale = np.abs(single).max()
    for name in list(rows)[1:]:
        diff = np.abs(np.asarray(outs[name]) - single).max()
        same = np.array_equal(np.asarray(outs[name]), np.asarray(outs[list(rows)[1]]))
        print(f"{name}: max |error - single run's| = {diff:.3g} m ({diff / scale:.2g} of max |error|); identical to threads=1: {same}")
    if client is not None:
        client.close()
    cores = os.cpu_count() or 1
    b1, b2 = list(rows)[1], list(rows)[cores]
    print(f"RATIO batch on 1 thread / one run at a time: {statistics.median(b / a for a, b in zip(wall[b1], wall[base])):.2f}x wall, "
          f"{statistics.median(b / a for a, b in zip(cpu[b1], cpu[base])):.2f}x cpu; "
          f"{cores} threads / 1 thread: {statistics.median(a / b for a, b in zip(wall[b1], wall[b2])):.2f}x wall")


if __name__ == "__main__":
    main()
