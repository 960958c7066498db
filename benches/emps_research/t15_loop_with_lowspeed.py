"""The package's own loop (gmsfric.loop.run_loop) on EMPS, unchanged except that the Stribeck
effect may have a level BELOW Coulomb (friction rising at low speed, 'velocity strengthening').
Monkeypatched here only; nothing under python/gmsfric is edited."""
import dataclasses, json, time
import numpy as np
from gmsfric.loop import load_axis_data, run_loop, LoopConfig, format_table
from gmsfric.loop import effects, select

D = '/work/shared/data/emps/'
est = load_axis_data(D + 'DATA_EMPS.mat', time='t', position='qm', command='vir', gain='gtau')
val = load_axis_data(D + 'DATA_EMPS_PULSES.mat', time='t', position='qm', command='vir', gain='gtau')


def fs_non_negative(p):
    # physical: the level at rest Fs = Fc + (Fs - Fc) stays >= 0 (it may lie below Fc)
    if "Fs_minus_Fc" in p and "Fc" in p and p["Fc"]["value"] + p["Fs_minus_Fc"]["value"] < 0:
        return "level at rest below zero"
    return None


eff = effects.CATALOGUE["stribeck"]
patched = dataclasses.replace(eff, physical=fs_non_negative)
effects.CATALOGUE["stribeck"] = patched
select.CATALOGUE["stribeck"] = patched
t0 = time.time()
res = run_loop(est, val, LoopConfig(progress=False))
print(format_table(res))
print(f"{time.time() - t0:.0f} s")
json.dump(res.as_dict(), open("t15_loop_with_lowspeed.json", "w"), indent=1, default=str)
