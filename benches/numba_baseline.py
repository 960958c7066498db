"""Headline benchmark: gmsfric against the numba loop a competent user writes, one process.

    python benches/numba_baseline.py                         # 1e7 steps, 1 warm-up, 5 interleaved repetitions
    python benches/numba_baseline.py --steps 1000000 --repeats 3
    python benches/numba_baseline.py --baseline PATH/numba_axis.py

The baseline is ``numba_axis.py`` (the project's shared speed anchor, by default
``/work/shared/bench/numba_axis.py``; only this script needs it, never the package): the paper's
axis in SI, exact-ZOH plant, the 1.3 ms delay as a ring buffer of 13 whole steps, PID
5e5 / 2.5e6 / 1e3 without derivative filter, a 4-block GMS updated explicitly per step, the
reference computed inside the loop, one output array (the tracking error).

gmsfric runs the same system: ``Plant(0.01985, 168.4, 176.8, delay=1.3e-3)``, ``PID(5e5, 2.5e6,
1e3)``, the same 4-block GMS in SI, dt = 1e-4 s, 10 mm / 0.01 Hz sine.  It is asked for the same
output: ``record=("error",)`` where ``simulate_closed_loop`` accepts ``record=`` (detected from
its signature), all outputs otherwise (the script says which).  The reference array is built
once outside the timing (numba computes it inside its loop; the cost of building it with numpy
is printed separately).

Second row: the straightforward numba transliteration of gmsfric's own algorithm (exact slip
update, linearly implicit coupling; ``compare.make_numba_plain``) on the same system, all five
outputs, as in earlier versions of ``BENCHMARKS.md``.

The implementations run interleaved (A B C, A B C, ...), so a change in machine load hits all
of them; the script prints min and median of steps/s (wall and process CPU time) and of the
per-repetition ratio gmsfric / baseline, and checks that the tracking errors agree.
"""

from __future__ import annotations

import argparse
import importlib.util
import inspect
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path
from types import ModuleType
from typing import Any, Callable

import numpy as np

import gmsfric as g
from gmsfric import _gmsfric

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compare  # noqa: E402  (same directory: the straightforward numba loop)

DEFAULT_BASELINE = "/work/shared/bench/numba_axis.py"
DT = 1e-4
AMP, FREQ = 0.01, 0.01  # reference: 10 mm, 0.01 Hz sine starting at 0 (as numba_axis.py)
KP, KI, KD = 5e5, 2.5e6, 1e3
DELAY = 1.3e-3
A, B, C = 0.01985, 168.4, 176.8
FC, FS, VS, SIGMA = 0.1826, 0.21, 0.00045, 6.9846
C_SLIP = 2222.2
ALPHA = np.array([0.033, 0.057, 0.0132, 0.0026]) / 0.1058
K = np.array([3264.7, 8.89, 23.79, 2.61]) * 1e3
ERROR_TOL = 1e-10  # agreement of the tracking errors the issue states (m)


def load_baseline(path: str) -> ModuleType:
    """Import ``run``/``setup`` from numba_axis.py with numba's cache in a private directory.

    numba's ``cache=True`` would otherwise write next to the shared file; and the module must be
    in ``sys.modules`` for a cached entry to load again.
    """
    if not Path(path).is_file():
        sys.exit(f"numba baseline not found at {path!r}: pass --baseline PATH/numba_axis.py "
                 "(the shared speed anchor; gmsfric itself does not need it)")
    os.environ.setdefault("NUMBA_CACHE_DIR", tempfile.mkdtemp(prefix="gmsfric-bench-numba-"))
    try:
        import numba  # noqa: F401
    except ImportError:
        sys.exit("numba is not installed: pip install 'gmsfric[bench]'")
    spec = importlib.util.spec_from_file_location("numba_axis", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["numba_axis"] = mod
    spec.loader.exec_module(mod)
    for name in ("run", "setup"):
        if not hasattr(mod, name):
            sys.exit(f"{path} has no `{name}`: expected numba_axis.py with run(n, dt, Phi, Gam, ...) and setup(dt)")
    return mod


def baseline_args(mod: ModuleType, n_blocks: int = 4) -> tuple:
    phi, gam = mod.setup(DT, A, B, C)
    alpha = np.resize(ALPHA, n_blocks)
    alpha = alpha / alpha.sum()
    k = np.resize(K, n_blocks)
    return (DT, phi, gam, int(round(DELAY / DT)), KP, KI, KD, AMP, FREQ, alpha, k, C_SLIP, FC, FS, VS, SIGMA, 1.0)


def gmsfric_system(n_blocks: int = 4) -> tuple[g.Plant, g.GMS, g.PID]:
    alpha = np.resize(ALPHA, n_blocks)
    gms = g.GMS(g.Stribeck(FC, FS, VS, 1.0), np.resize(K, n_blocks), alpha / alpha.sum(), C_SLIP, SIGMA)
    return g.Plant(A, B, C, delay=DELAY), gms, g.PID(KP, KI, KD)


def reference(n: int) -> np.ndarray:
    return AMP * np.sin(2 * np.pi * FREQ * np.arange(n) * DT)


def record_kwargs() -> tuple[dict[str, Any], str]:
    """``record=("error",)`` if ``simulate_closed_loop`` takes it (a keyword of ``RunOptions``),
    else nothing (all outputs)."""
    opts = getattr(g, "RunOptions", None)
    if "record" in inspect.signature(g.simulate_closed_loop).parameters or "record" in getattr(opts, "__annotations__", {}):
        return {"record": ("error",)}, 'record=("error",)'
    return {}, "all outputs (this gmsfric has no record=)"


def plain_args(plant: g.Plant, gms: g.GMS, pid: g.PID) -> tuple:
    """Arguments of ``compare.make_numba_plain()`` for this system."""
    phi, g_old, g_new, g_f, m = plant._native.discretize(DT)
    st = gms.stribeck
    return (DT, np.array(phi), np.array(g_old), np.array(g_new), np.array(g_f), m, pid.kp, pid.ki, pid.kd, pid.tf,
            float(pid.u_min), float(pid.u_max), st.fc, st.fs, st.vs, st.delta, gms.c, gms.sigma, np.array(gms.k), np.array(gms.alpha))


def timed(fn: Callable[[], Any]) -> tuple[Any, float, float]:
    # Process CPU time: gmsfric may compute on a helper thread (the caller polls for Ctrl-C).
    c0, w0 = time.process_time(), time.perf_counter()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def summary(values: list[float]) -> str:
    return f"{min(values):.3e} / {statistics.median(values):.3e}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=10_000_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--blocks", type=int, default=4, help="GMS blocks (numba_axis.py repeats its 4 blocks)")
    ap.add_argument("--baseline", default=DEFAULT_BASELINE, help="path of numba_axis.py")
    ap.add_argument("--no-plain", action="store_true", help="skip the straightforward numba row")
    ap.add_argument("--warmup", type=int, default=1, help="untimed full-size calls of every row first (the process's first "
                    "large allocation takes memory the host has not mapped yet, whoever makes it)")
    args = ap.parse_args(argv)
    n = args.steps
    mod = load_baseline(args.baseline)
    import numba

    load = os.getloadavg()
    print(f"# gmsfric {_gmsfric.__version__} | numba {numba.__version__} | numpy {np.__version__} | Python {platform.python_version()} | "
          f"{os.cpu_count()} logical CPUs | load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    kwargs, what = record_kwargs()
    print(f"# {n:.0e} steps, dt = {DT:g} s, GMS N = {args.blocks}, {args.repeats} interleaved repetitions; gmsfric records {what}")

    bargs = baseline_args(mod, args.blocks)
    plant, gms, pid = gmsfric_system(args.blocks)
    ref_wall = min(timed(lambda: reference(n))[1] for _ in range(3))
    ref = reference(n)

    def run_gmsfric() -> np.ndarray:
        return g.simulate_closed_loop(plant, gms, pid, ref, DT, **kwargs).error

    rows: dict[str, Callable[[], np.ndarray]] = {
        "gmsfric simulate_closed_loop": run_gmsfric,
        "numba_axis.py run (competent user)": lambda: mod.run(n, *bargs),
    }
    if not args.no_plain:
        plain = compare.make_numba_plain()
        pargs = plain_args(plant, gms, pid)
        plain(ref[:1000], *pargs)  # compile outside the timing
        rows["numba straightforward transliteration"] = lambda: ref - plain(ref, *pargs)[0]
    mod.run(1000, *bargs)  # compile outside the timing

    for _ in range(args.warmup):
        for run in rows.values():
            run()
    wall: dict[str, list[float]] = {k: [] for k in rows}
    cpu: dict[str, list[float]] = {k: [] for k in rows}
    errors: dict[str, np.ndarray] = {}
    for rep in range(args.repeats):
        names = list(rows)
        names = names[rep % len(names):] + names[: rep % len(names)]  # rotate who goes first
        for name in names:
            err, w, c = timed(rows[name])
            wall[name].append(w)
            cpu[name].append(c)
            if rep == 0:
                errors[name] = np.array(err, copy=True)
            del err

    gname = "gmsfric simulate_closed_loop"
    print("\n| implementation | outputs | wall steps/s min / median | cpu steps/s min / median | "
          "gmsfric x, wall: min / median per repetition | gmsfric x, cpu: min / median |")
    print("|---|---|---|---|---|---|")
    for name in rows:
        rate_w = [n / t for t in wall[name]]
        rate_c = [n / t for t in cpu[name]]
        if name == gname:
            outputs, ratio_w, ratio_c = what.split(" (")[0], "1", "1"
        else:
            rw = [b / a for a, b in zip(wall[gname], wall[name])]
            rc = [b / a for a, b in zip(cpu[gname], cpu[name])]
            ratio_w = f"{min(rw):.2f} / {statistics.median(rw):.2f}"
            ratio_c = f"{min(rc):.2f} / {statistics.median(rc):.2f}"
            outputs = "error" if "numba_axis" in name else "all 5"
        print(f"| {name} | {outputs} | {summary(rate_w)} | {summary(rate_c)} | {ratio_w} | {ratio_c} |")

    for name in rows:
        print(f"# {name}: wall ms per repetition, in order: {' '.join(f'{w * 1e3:.0f}' for w in wall[name])}")

    base = errors["numba_axis.py run (competent user)"]
    diff = np.abs(errors[gname] - base)
    settle = min(n, int(round(0.1 / DT)))
    verdict = "within" if diff.max() <= ERROR_TOL else "NOT within"
    print(f"\nTracking errors, gmsfric vs numba_axis.py: max |e| = {np.abs(base).max():.4g} m, max |diff| = {diff.max():.3g} m "
          f"at t = {diff.argmax() * DT:.4g} s ({verdict} {ERROR_TOL:g} m); after the first {settle * DT:g} s: "
          f"{diff[settle:].max() if n > settle else 0.0:.3g} m")
    if "numba straightforward transliteration" in errors:
        d2 = np.abs(errors["numba straightforward transliteration"] - errors[gname]).max()
        print(f"Straightforward numba vs gmsfric (same algorithm): max |diff| of the error = {d2:.3g} m")
    print(f"Building the reference with numpy ({n:.0e} samples) takes {ref_wall:.3f} s (best of 3) = {ref_wall / n * 1e9:.1f} ns/step "
          "(outside gmsfric's timing; numba_axis.py computes its sine inside the loop).")
    touch = min(timed(lambda: np.ones(n))[1] for _ in range(3))
    print(f"Fresh memory: allocating and writing one {n:.0e}-sample float64 array takes {touch:.3f} s (best of 3) = "
          f"{touch / n * 1e9:.1f} ns/step per recorded output (page faults; every implementation pays it per output array).")
    bname = "numba_axis.py run (competent user)"
    gw, bw = statistics.median(wall[gname]), statistics.median(wall[bname])
    gc, bc = statistics.median(cpu[gname]), statistics.median(cpu[bname])
    print(f"RATIO gmsfric / numba_axis.py: best times {min(wall[bname]) / min(wall[gname]):.2f}x, median times "
          f"{bw / gw:.2f}x (wall); best {min(cpu[bname]) / min(cpu[gname]):.2f}x, median {bc / gc:.2f}x (process CPU); "
          f"median wall including the reference build: {bw / (gw + ref_wall):.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
