"""Batch scaling: the same batch of closed-loop runs on 1, 2, ... threads (one process).

    python benches/batch_scaling.py [--runs 16] [--steps 500000]

Each run is the paper's axis (4-block GMS, PID, 1.29 ms delay) with a different PID gain; the
batch goes through ``gmsfric.batch.simulate_batch(..., threads=k)``.  Also times the same runs
as a Python loop over ``simulate_closed_loop`` (one core) for reference.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from gmsfric import simulate_closed_loop
from gmsfric.batch import simulate_batch

import compare  # noqa: E402  (same directory: the shared axis definition)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", type=int, default=16)
    ap.add_argument("--steps", type=int, default=500_000)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    ref = compare.reference(args.steps)
    ctrls = [compare.PID(kp, 2.5e6, 1.0e3, 5e-4, -10.0, 10.0) for kp in np.linspace(3e5, 8e5, args.runs)]
    total = args.runs * args.steps
    print(f"# {args.runs} runs x {args.steps} steps = {total:.1e} steps; {os.cpu_count()} logical CPUs\n")
    print("| how | threads | wall s | steps/s | speed-up vs 1 thread |")
    print("|---|---|---|---|---|")
    t0 = time.perf_counter()
    singles = [simulate_closed_loop(compare.PLANT, compare.GMS4, c, ref, compare.DT).position for c in ctrls]
    loop = time.perf_counter() - t0
    print(f"| Python loop of simulate_closed_loop | 1 | {loop:.2f} | {total / loop:.3e} | - |")
    base = None
    for threads in range(1, (os.cpu_count() or 1) + 1):
        best = np.inf
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            res = simulate_batch(compare.PLANT, compare.GMS4, ctrls, ref, compare.DT, threads=threads, progress=False)
            best = min(best, time.perf_counter() - t0)
        assert all(np.array_equal(res.position[i], singles[i]) for i in range(args.runs))
        base = base or best
        print(f"| simulate_batch | {threads} | {best:.2f} | {total / best:.3e} | {base / best:.2f} |")


if __name__ == "__main__":
    main()
