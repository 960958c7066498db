#!/usr/bin/env python
"""Follow-up probe: does `friction_drift` transfer between runs of different durations?

The planted drift has the same time constant in seconds on both runs.  This re-runs the tool on
an audited case with the estimation log cut to the validation log's duration (same rig, same
law, the first part of the same estimation run) and prints what is accepted.

    python probe_drift.py --out /tmp/audit2_main s068_friction_drift p094_presliding_hysteresis+friction_drift
"""
from __future__ import annotations

import argparse
import json
import os
import shlex
import subprocess


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", required=True, help="the audit's output folder")
    ap.add_argument("--work", default="/tmp/audit2_probe_drift")
    ap.add_argument("cases", nargs="+")
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    for c in a.cases:
        d = os.path.join(a.out, c)
        with open(os.path.join(d, "result.json")) as fh:
            R = json.load(fh)
        with open(os.path.join(d, "truth.json")) as fh:
            T = json.load(fh)
        with open(os.path.join(d, "est.csv")) as fh:
            est = fh.read().splitlines()
        with open(os.path.join(d, "val.csv")) as fh:
            val = fh.read().splitlines()
        t_end = float(val[-1].split(",")[0])
        keep = [est[0]] + [ln for ln in est[1:] if float(ln.split(",")[0]) <= t_end]
        cut = os.path.join(a.work, f"{c}_est_cut.csv")
        with open(cut, "w") as fh:
            fh.write("\n".join(keep) + "\n")
        args = shlex.split(R["cmd"])
        args[args.index(os.path.join(d, "est.csv"))] = cut
        out = os.path.join(a.work, f"{c}_cut.json")
        args[args.index(os.path.join(d, "tool.json"))] = out
        subprocess.run(args, capture_output=True, text=True)
        with open(out) as fh:
            J = json.load(fh)
        scale = 1e3 if T["units"]["time"] == "ms" else 1.0
        print(f"{c}: est {T['runs']['est']['duration']:.1f} s, val {T['runs']['val']['duration']:.1f} s; "
              f"audit accepted {R.get('effects')}; est cut to {t_end / scale:.1f} s -> {J['final']['effects']}")
        for s in J["steps"]:
            if s["effect"] == "friction_drift":
                print(f"    r{s['round']} accepted={s['accepted']}: {s['reason'][:160]}")


if __name__ == "__main__":
    main()
