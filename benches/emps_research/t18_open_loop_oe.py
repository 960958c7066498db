"""Open-loop output-error fits on the EMPS estimation run with the package's fitter
(gmsfric.output_error, growing horizons), started from the branch's refined models, scored by the
benchmark's protocol on both runs. Diagnostic: the research (t10) found this cost a flat valley."""
import json
import time

import gmsfric
from gmsfric.loop import load_axis_data
from gmsfric.loop.simulation import open_loop_rmse
from gmsfric.output_error import default_parameters, fit_output_error
from gmsfric.loop.closedloop import initial_state

D = "/work/shared/data/emps/"
COLS = dict(time="t", position="qm", command="vir", gain="gtau", reference="qg")
est = load_axis_data(D + "DATA_EMPS.mat", **COLS)
val = load_axis_data(D + "DATA_EMPS_PULSES.mat", disturbance="pulses_N", **COLS)
q0, v0 = initial_state(est.t, est.position)
for src in ("emps_fit_simulation.json", "t17_fit_simulation.json"):
    start = gmsfric.load_model(src)
    t0 = time.time()
    r = fit_output_error(start, est.dt, est.position, command=est.command, skip=20, initial_position=q0, initial_velocity=v0,
                         parameters=[p for p in default_parameters(start) if p != "plant.delay"], progress=False)
    print(f"{src}: start open-loop RMSE est {1e3 * open_loop_rmse(start, est):.3f} mm, pulses {1e3 * open_loop_rmse(start, val):.3f} mm")
    print(f"  open-loop OE on est ({r.n_simulations} simulations, {time.time() - t0:.0f} s): est {1e3 * open_loop_rmse(r.model, est):.3f} mm, "
          f"pulses {1e3 * open_loop_rmse(r.model, val):.3f} mm")
    print("  " + r.table().replace("\n", "\n  "))
