"""What `gmsfric loop --fit simulation --open-loop` gives on EMPS once the loop accepts a Stribeck
level below Coulomb (the catalogue change t15 patches at runtime; another branch owns it): the
package's loop (patched as in t15), then the package's own simulation refinement and scores
(gmsfric.loop.simulation.add_simulation). Nothing under python/gmsfric is edited here."""
import dataclasses
import json
import time

from gmsfric import presets
from gmsfric.loop import LoopConfig, effects, load_axis_data, run_loop, select
from gmsfric.loop.simulation import add_simulation

D = "/work/shared/data/emps/"
COLS = dict(time="t", position="qm", command="vir", gain="gtau", reference="qg")
est = load_axis_data(D + "DATA_EMPS.mat", **COLS)
val = load_axis_data(D + "DATA_EMPS_PULSES.mat", disturbance="pulses_N", **COLS)


def fs_non_negative(p):
    if "Fs_minus_Fc" in p and "Fc" in p and p["Fc"]["value"] + p["Fs_minus_Fc"]["value"] < 0:
        return "level at rest below zero"
    return None


patched = dataclasses.replace(effects.CATALOGUE["stribeck"], physical=fs_non_negative)
effects.CATALOGUE["stribeck"] = select.CATALOGUE["stribeck"] = patched
t0 = time.time()
res = run_loop(est, val, LoopConfig(progress=False))
for fit in (False, True):
    r = add_simulation(res, presets.emps_controller(), fit=fit, open_loop=True, progress=False)
    if not fit:  # the inverse models simulated as they are
        from gmsfric.loop import closed_loop_report
        r.closed_loop, _ = closed_loop_report({"baseline": r.baseline, "final": r.final}, {"estimation": r.split.est, "validation": r.split.val}, presets.emps_controller())
    print(f"=== --fit {'simulation' if fit else 'inverse'}")
    print(r.table())
    with open(f"t17_fit_{'simulation' if fit else 'inverse'}.json", "w") as f:
        f.write(r.to_json())
print(f"{time.time() - t0:.0f} s")
