"""Regenerate the small example files shipped in python/gmsfric/data (run from the repo root).

- emps_excerpt.csv: 10 s of the EMPS estimation run (t, qm, qg, vir at 1 kHz; gtau in the
  header comment of the README), from ../shared/data/emps/DATA_EMPS.mat.
- presliding_example.csv: a virtual-rig pre-sliding test on the paper's GMS (small and large
  sinusoids at 0.1 Hz, force with 0.2 mN noise, 1 nm encoder), made by gmsfric itself.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.io import loadmat

import gmsfric as g
from gmsfric import presets

OUT = Path("python/gmsfric/data")


def emps_excerpt() -> None:
    d = loadmat("../shared/data/emps/DATA_EMPS.mat")
    sl = slice(0, 10000)
    cols = {k: np.asarray(d[k]).ravel()[sl] for k in ("t", "qm", "qg", "vir")}
    header = "t,qm,qg,vir"
    data = np.column_stack([cols[k] for k in ("t", "qm", "qg", "vir")])
    np.savetxt(OUT / "emps_excerpt.csv", data, delimiter=",", header=header, comments="", fmt=["%.3f", "%.8e", "%.8e", "%.5e"])


def presliding_example() -> None:
    rng = np.random.default_rng(7)
    dt = 5e-3
    t = np.arange(0, 20.0, dt)
    # 10 s small (2 µm) then 10 s large (30 µm: beyond the last block's 12.7 µm break) amplitude, 0.1 Hz
    amp = np.where(t < 10.0, 2e-6, 30e-6)
    x = amp * np.sin(2 * np.pi * 0.1 * t)
    gms = presets.paper_gms()
    f = g.simulate_friction(gms, t, x) + rng.normal(0, 2e-4, t.size)
    xq = np.round(x / 1e-9) * 1e-9
    np.savetxt(OUT / "presliding_example.csv", np.column_stack([t, xq, f]), delimiter=",", header="time,position,force", comments="", fmt=["%.4f", "%.4e", "%.5e"])


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    emps_excerpt()
    presliding_example()
