"""Where a run's timing lies: the shift the *true* model fits best, per run, on planted-delay cases.

    python benches/loop_campaign/delay_timing.py --seed 69              # every simulated delay case
    python benches/loop_campaign/delay_timing.py --seed 69 --ideal      # also without quantization and noise

The loop chooses a delay on the estimation run and must confirm it on the held-out run.  This
measures, with the planted model's own columns (``truth.errors``: baseline plus the other planted
effects, only the linear coefficients fitted), the total force shift (planted delay plus the
sampling hold, in samples) that each run prefers on its moving rows, on a grid of a quarter
sample.  When the two runs prefer different shifts, no delay chosen on the first can confirm
on the second, however it is chosen.  ``--ideal`` re-simulates each case with the encoder's
quantization made negligible and no force noise, to see which part of the disagreement they cause.
Columns ``gain`` and ``reach``: the true model's held-out gain over the timing alignment with the
planted delay (the ground truth's ``gain_beyond_null``) and with the shift the estimation run
prefers, the most that a delay chosen on the estimation run can gain.
No line of ``gmsfric.loop`` is used beyond the public preprocessing the ground truth shares.
"""

from __future__ import annotations

import argparse
import copy
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

if __package__ in (None, ""):  # run as a script: make the package importable
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

import numpy as np  # noqa: E402

from .cases import make_cases  # noqa: E402
from .rigs import simulate_run  # noqa: E402
from .truth import DETECTABLE, STANDSTILL, _base_columns, _rows, effect_columns, errors, true_signals  # noqa: E402

#: Shifts tried (samples of the logged rate), up to twice the planted one.
STEP = 0.25

#: ``--fast``: rows at least this fraction of the estimation run's 99th-percentile speed.
FAST = 0.2


def _best(sig: Any, others: list[dict[str, Any]], off: bool, grid: Any, v_min: float) -> float:
    """The shift (samples) with the smallest residual of the true model fitted on ``sig``'s rows
    faster than ``v_min``."""
    cols = _base_columns(sig, off) + [c for e in others for c in effect_columns(e, sig)]
    rows = np.abs(sig.rows["qd"]) >= v_min
    y = sig.y[rows]
    sse = []
    for s in grid:
        X = _rows(cols, sig, s * sig.dt)[rows]
        scale = np.sqrt((X**2).sum(axis=0))
        scale[scale == 0] = 1.0
        r = y - X @ (np.linalg.lstsq(X / scale, y, rcond=None)[0] / scale)
        sse.append(float(r @ r))
    return float(grid[int(np.argmin(sse))])


@dataclass
class Timing:
    """Total force shifts (samples of the logged rate) of one planted-delay case: the planted one
    (delay plus sampling hold) and the ones the true model fits best on each run's moving rows
    (``*_fast``: only on the rows faster than :data:`FAST` of the top speed); and the true model's
    held-out gains over the timing alignment (the shift within one sample that the estimation run
    prefers, the loop's null for a delay) with the planted shift (``gain``, the ground truth's
    ``gain_beyond_null`` of a single delay) and with the one the estimation run prefers
    (``reach``: the most that a delay chosen on that run can gain)."""

    true: float
    est: float
    val: float
    est_fast: float
    val_fast: float
    gain: float
    reach: float


def timing(case: dict[str, Any]) -> Timing:
    """Simulate both runs of ``case`` once and measure its :class:`Timing`."""
    est, val = simulate_run(case, "est"), simulate_run(case, "val")
    se, sv = true_signals(case, est, val)
    others = case.get("native", []) + [e for e in case["effects"] if e["name"] != "input_delay"]
    tau = next(e["tau"] for e in case["effects"] if e["name"] == "input_delay")
    off = case.get("baseline", "reference") == "reference"
    true = (tau + est.hold) / se.dt
    grid = np.arange(0.0, max(8.0, 2.0 * true) + 1e-9, STEP)
    top = float(np.percentile(np.abs(se.rows["qd"]), 99))
    best = {k: _best(sig, others, off, grid, frac * top) for k, sig, frac in
            (("est", se, STANDSTILL), ("val", sv, STANDSTILL), ("est_fast", se, FAST), ("val_fast", sv, FAST))}
    fit = lambda s: errors(se, sv, others, s * se.dt, off, moving=True)  # noqa: E731
    null = min(fit(k / 10) for k in range(11))[1]  # the alignment the estimation rows choose
    return Timing(true=true, **best, gain=(null - fit(true)[1]) / null, reach=(null - fit(best["est"])[1]) / null)


def idealised(case: dict[str, Any]) -> dict[str, Any]:
    """The case with an encoder step a thousand times finer and no force noise."""
    out = copy.deepcopy(case)
    out["rig"]["quant"] = 1e-3 * out["rig"]["quant"]
    out["rig"]["noise"] = 0.0
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=2024, help="campaign seed (as run.py --seed)")
    ap.add_argument("--ideal", action="store_true", help="also re-simulate without quantization and force noise")
    ap.add_argument("--fast", action="store_true", help=f"also choose on the rows faster than {FAST:.0%} of the top speed")
    args = ap.parse_args(argv)
    cases = [c for c in make_cases(args.seed) if c["sim"] in ("own", "core")
             and any(e["name"] == "input_delay" for e in c["effects"])]
    print(f"{len(cases)} simulated cases with a planted delay (seed {args.seed}); shifts in samples of the log")
    head = f"{'case':52s} {'est':>9s} {'val':>9s} {'true':>5s} {'est':>5s} {'val':>5s} {'gain':>6s} {'reach':>6s}"
    print(head + ("  ideal: est   val" if args.ideal else "") + ("  fast: est   val" if args.fast else ""))
    rows = []
    for case in cases:
        tm = timing(case)
        line = (f"{case['id']:52s} {case['traj']['est']['kind']:>9s} {case['traj']['val']['kind']:>9s} {tm.true:5.2f} {tm.est:5.2f} {tm.val:5.2f}"
                f" {tm.gain:6.3f} {tm.reach:6.3f}")
        ideal = timing(idealised(case)) if args.ideal else None
        if ideal is not None:
            line += f"        {ideal.est:5.2f} {ideal.val:5.2f}"
        if args.fast:
            line += f"       {tm.est_fast:5.2f} {tm.val_fast:5.2f}"
        print(line, flush=True)
        rows.append((case["traj"]["est"]["kind"], tm.true, tm.est, tm.val, ideal.est if ideal else np.nan, ideal.val if ideal else np.nan,
                     tm.est_fast if args.fast else np.nan, tm.val_fast if args.fast else np.nan, tm.gain, tm.reach))
    a = np.array([r[1:] for r in rows], dtype=float)
    kinds = np.array([r[0] for r in rows])
    det, reach = a[:, 7] >= DETECTABLE, a[:, 8] >= DETECTABLE
    print(f"\nbeyond the alignment (gain >= {DETECTABLE:.0%}): with the planted delay {det.sum()} of {det.size}; "
          f"with the shift the estimation run prefers {reach.sum()} ({(det & reach).sum()} of the {det.sum()})")
    print("bias of the best shift (samples): median, and share of runs off by more than half a sample")
    for name, col in (("estimation run", 1), ("validation run", 2), ("estimation, ideal", 3), ("validation, ideal", 4),
                      ("estimation, fast", 5), ("validation, fast", 6)):
        d = a[:, col] - a[:, 0]
        if np.all(np.isfinite(d)):
            print(f"  {name:20s} median {np.median(d):+.2f}, |off| > 0.5: {np.mean(np.abs(d) > 0.5):.0%}")
    for name, cols in (("", (1, 2)), (", ideal", (3, 4)), (", fast", (5, 6))):
        d = a[:, cols[0]] - a[:, cols[1]]
        if np.all(np.isfinite(d)):
            print(f"  runs disagreeing by more than half a sample{name}: {np.mean(np.abs(d) > 0.5):.0%}")
    for k in sorted(set(kinds)):
        d = a[kinds == k, 1] - a[kinds == k, 0]
        print(f"  estimation run {k:9s} (n = {d.size:2d}): median bias {np.median(d):+.2f}, |off| > 0.5: {np.mean(np.abs(d) > 0.5):.0%}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
