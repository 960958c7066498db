"""Calibration of the output-error standard errors on known-truth rigs (the rigs of
tests/test_output_error.py): over many noise realisations, z = (estimate - truth) / stated std
should have an RMS near 1.  Also the inverse model's z on the same data (biased rigs).

    ../../.venv/bin/python oe_rig_calibration.py [seeds]      # writes oe_rig_calibration.log
"""
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))
from test_output_error import PATHS, closed_loop_run, fit_output_error, inverse_model_start, open_loop_run, z_scores  # noqa: E402

N = int(sys.argv[1]) if len(sys.argv) > 1 else 20
KEYS = ("mass", "friction.sigma", "friction.stribeck.fc", "friction.offset")
IDIM = {"mass": "M", "friction.sigma": "Fv", "friction.stribeck.fc": "Fc", "friction.offset": "offset"}
TRUE = {"M": 60.0, "Fv": 150.0, "Fc": 15.0, "offset": -2.0}
lines = []
for mode, make in (("open loop, 200 Hz, 20 um noise", lambda s: (open_loop_run(200.0, 20e-6, s), None)),
                   ("closed loop, 250 Hz, 2 um noise", lambda s: closed_loop_run(250.0, 2e-6, s))):
    Z, ZI, sims = [], [], []
    for seed in range(N):
        d, ctrl = make(seed)
        start, idim = inverse_model_start(d)
        if ctrl is None:
            r = fit_output_error(start, d.dt, d.position, command=d.command, parameters=PATHS, initial_position=0.0, initial_velocity=0.0, progress=False)
        else:
            r = fit_output_error(start, d.dt, d.position, reference=d.reference, controller=ctrl, measured_command=d.command, parameters=PATHS, progress=False)
        z = z_scores(r)
        Z.append([z[k] for k in KEYS])
        ZI.append([(idim[IDIM[k]]["value"] - TRUE[IDIM[k]]) / idim[IDIM[k]]["std"] for k in KEYS])
        sims.append(r.n_simulations)
    Z, ZI = np.array(Z), np.array(ZI)
    lines.append(f"{mode}, {N} seeds, parameters {KEYS}")
    lines.append(f"  output error: RMS z {np.round(np.sqrt((Z**2).mean(0)), 2)}, mean z {np.round(Z.mean(0), 2)}, max |z| {np.round(np.abs(Z).max(0), 2)}, "
                 f"fraction |z| < 2: {np.round((np.abs(Z) < 2).mean(0), 2)}; simulations per fit {int(np.median(sims))} (median)")
    lines.append(f"  inverse model: RMS z {np.round(np.sqrt((ZI**2).mean(0)), 1)}, mean z {np.round(ZI.mean(0), 1)}")
    print("\n".join(lines[-3:]), flush=True)
Path(__file__).with_suffix(".log").write_text("\n".join(lines) + "\n")
