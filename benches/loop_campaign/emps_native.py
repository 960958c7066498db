"""Which effects does the real EMPS axis have of its own?  (``python benches/loop_campaign/emps_native.py``)

An effect is *native* to the recordings when its true column is detectable on the unmodified runs
by the campaign's own rule (:data:`truth.DETECTABLE`: the held-out error falls by >= 10 %
relative), with its nonlinear parameters chosen on the estimation run only.  Native effects are
part of every EMPS case's true model, and accepting them is not false.  The viscous asymmetry is
one (the axis slides ~171 N s/m in +q and ~245 in -q); this script measures the low-speed
friction curve on top of it: a grid of Stribeck shapes (``exp(-x)``, ``exp(-x^2)``, Lorentzian)
and widths, in both directions (estimation on one run, error on the other).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    __package__ = "loop_campaign"

from . import cases, rigs, truth  # noqa: E402


def main() -> None:
    asym = [{"name": "asymmetric_friction", "dFv": 1.0}]
    for direction in ("forward", "swapped"):
        case = {"files": cases.EMPS_FILES[direction], "effects": [], "seed": 1}
        est, val = rigs.emps_run(case, "est"), rigs.emps_run(case, "val")
        se, sv = truth.signals(est, val)
        base = truth.errors(se, sv, asym, est.hold, True)
        fits = []
        for kind, delta in ((0, 1.0), (0, 2.0), (1, 2.0)):
            for vs in np.geomspace(0.002, 0.05, 15):
                strib = {"name": "stribeck", "vs": float(vs), "kind": kind, "delta": delta}
                e = truth.errors(se, sv, asym + [strib], est.hold, True)
                fits.append((e[0], e[1], strib))
        e_est, e_val, strib = min(fits, key=lambda f: f[0])  # chosen on the estimation run
        gain = (base[1] - e_val) / base[1]
        print(f"{direction}: est {cases.EMPS_FILES[direction]['est']}, baseline + asymmetry {base[0]:.3f} / {base[1]:.3f} %; "
              f"+ Stribeck {strib} {e_est:.3f} / {e_val:.3f} %: held-out gain {100 * gain:.1f} % "
              f"({'native' if gain >= truth.DETECTABLE else 'not detectable'})")
    print(f"cases.EMPS_NATIVE: {cases.EMPS_NATIVE}")


if __name__ == "__main__":
    main()
