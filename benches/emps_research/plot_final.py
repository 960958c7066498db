"""Figures of the final model (the loop's IDIM model with the low-speed term and 0.3 ms delay,
simulated as is): closed-loop force error, pulse-edge responses, open-loop position error."""
import json
import numpy as np
from matplotlib.figure import Figure
from emps import *
import plot_closedloop, plot_openloop, edges

FINAL = json.load(open("t16_final.json"))["IDIM final (loop), simulated as is"]["params"]
m = Model(FINAL, [])
plot_closedloop.figure(m, "final_closedloop.png", zoom=(2.3, 2.45))
plot_openloop.figure(m.unpack()[0], "final_openloop.png", nsub=10)
out = edges.edge_average(m)
fig = Figure(figsize=(12, 4)); axs = fig.subplots(1, 2)
for j, (kind, (t, fm, fs, dq)) in enumerate(out.items()):
    axs[j].plot(t * 1e3, fm, label="measured"); axs[j].plot(t * 1e3, fs, label="simulated")
    axs[j].plot(t * 1e3, fs - fm, label="sim - meas"); axs[j].legend(); axs[j].set_title(f"{kind} pulse edges (mean)")
    axs[j].set_xlabel("time from edge (ms)"); axs[j].set_ylabel("force - force before edge (N)")
fig.tight_layout(); fig.savefig("final_edges.png", dpi=70)
