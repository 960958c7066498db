"""``gmsfric paper``: replay the paper's identification on the virtual rig, end to end.

The rig carries the paper's numbers (``presets.paper_*`` under a :class:`PaperReading`); every
experiment of the paper is run on it (constant-velocity ramps, small/large sinusoids,
band-limited noise), the identification pipeline is applied to the simulated records, and for
every table of the paper the printed, true (rig) and identified values are printed.

Table 3 is garbled in the source (10 numbers for 12 cells).  :class:`Table3Reading` holds how it is
read; see ``docs/identification.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import presets
from ..models import StaticFriction, Stribeck
from ..presets import PaperReading, Table3Reading
from ..system import Plant
from .frf import estimate_frf, fit_plant
from .presliding import fit_presliding
from .results import Replay
from .revision import revise_plant
from .rig import VirtualRig
from .static_map import fit_static_map_from_run

PAPER_VELOCITIES_MM_S = (0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1, 0.2, 0.3, 0.4, 0.5, 0.8, 1, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 25, 30)


@dataclass(frozen=True)
class ReplaySettings:
    """Everything the replay assumes beyond the paper's printed numbers (all overridable).

    ``reading.drive_limit`` defaults to 1000 V here: eq. 1 needs ``b v / a`` = 255 V to hold
    30 mm/s, beyond the paper's +-100 V, so the paper's own velocity list could not be run under it.
    The virgin-curve test uses a 1 nm position sensor: the paper's 0.5 um encoder cannot resolve
    the 10-20 nm first block (the paper's Fig. 6 amplitudes are below one encoder count).
    """

    reading: PaperReading = PaperReading(drive_limit=1000.0)
    table3: Table3Reading = Table3Reading()
    mechanics: Plant | None = None  # None: eq. 1 is the rig's true mechanics
    dt: float = 1e-3
    encoder: float = 0.5e-6
    static_force_noise: float = 2e-3
    velocities: tuple[float, ...] = tuple(v * 1e-3 for v in PAPER_VELOCITIES_MM_S)
    min_travel: float = 100e-6
    max_travel: float = 4e-3
    presliding_resolution: float = 1e-9
    presliding_force_noise: float = 2e-4
    sine_amplitudes: tuple[float, float] = (2e-6, 30e-6)
    sine_frequency: float = 0.1
    sine_cycles: int = 2
    n_blocks: int | None = 4
    frf_dt: float = 5e-4
    frf_duration: float = 30.0
    frf_rms: float = 5.0
    frf_band: tuple[float, float] = (0.5, 300.0)
    frf_fit_band: tuple[float, float] = (1.0, 300.0)
    seed: int = 0


def _row(name: str, unit: str, printed: float | None, true: float, value: float, stderr: float) -> dict[str, Any]:
    z = (value - true) / stderr if stderr and np.isfinite(stderr) and stderr > 0 else None
    return {"name": name, "unit": unit, "printed": printed, "true": true, "value": value, "stderr": stderr, "z": z}


def replay_paper(settings: ReplaySettings = ReplaySettings(), *, progress: bool = True) -> Replay:
    """Run the paper's experiments on the virtual rig and identify everything again.

    Returns
    -------
    Replay
        The identification results and, in ``tables``, printed / true / identified values.
    """
    s = settings
    rd = s.reading
    gms = presets.paper_gms(rd)
    plant = s.mechanics or presets.paper_plant(rd)
    pid = presets.paper_pid(rd)
    rng_seeds = np.random.SeedSequence(s.seed).generate_state(4)

    # Table 1: constant-velocity ramps under PID (paper Section 3.1, Figs. 4-5)
    rig = VirtualRig(plant, gms, pid, dt=s.dt, encoder=s.encoder, force_noise=s.static_force_noise, drive_limit=rd.drive_limit)
    run = rig.constant_velocity_run(s.velocities, min_travel=s.min_travel, max_travel=s.max_travel, seed=int(rng_seeds[0]))
    sm = fit_static_map_from_run(run["t"], run["position"], run["force"], progress=progress)
    st = Stribeck(sm.value("fc"), max(sm.value("fs"), 0.0), sm.value("vs"), sm.value("delta"))

    # Table 2: small and large sinusoids at one frequency (Section 3.2, Figs. 6-8)
    prig = rig.with_(encoder=s.presliding_resolution, force_noise=s.presliding_force_noise)
    sine = prig.sinusoid_test(s.sine_amplitudes, s.sine_frequency, cycles=s.sine_cycles, seed=int(rng_seeds[1]))
    st_se = {k: sm.stderr(k) for k in ("fc", "fs", "vs", "delta")}
    ps = fit_presliding(sine["t"], sine["position"], sine["force"], n_blocks=s.n_blocks, stribeck=st, stribeck_stderr=st_se, sigma=sm.value("sigma"), progress=progress)

    # Eq. 1: band-limited noise, H1, NLS (Section 2, Fig. 3)
    frig = rig.with_(dt=s.frf_dt)
    noise = frig.noise_test(s.frf_duration, s.frf_rms, s.frf_band, seed=int(rng_seeds[2]))
    frf = estimate_frf(noise["t"], noise["input"], noise["output"])
    pf = fit_plant(frf, fmin=s.frf_fit_band[0], fmax=s.frf_fit_band[1], force_gain=plant.force_gain)
    p0 = pf.model_object

    # Table 3: revision with each identified friction model in the loop (Section 4.1, Figs. 10-13)
    static_model = StaticFriction(st, sigma=sm.value("sigma"))
    band = dict(fmin=s.frf_fit_band[0], fmax=s.frf_fit_band[1])
    rv_s = revise_plant(noise["t"], noise["input"], noise["output"], static_model, p0, progress=progress, **band)
    rv_g = revise_plant(noise["t"], noise["input"], noise["output"], ps.model_object, p0, progress=progress, **band)

    # ---- tables ---------------------------------------------------------------------------
    t1 = presets.PAPER_TABLE1
    gst = gms.stribeck
    truth: dict[str, Any] = {"fc": gst.fc, "fs": gst.fs, "vs": gst.vs, "sigma": gms.sigma, "delta": gst.delta}
    tables: dict[str, list[dict[str, Any]]] = {}
    tables["Table 1: static friction model (eq. 2)  [SI: N, m/s, N s/m]"] = [
        _row("Fc", "N", t1["fc"], gst.fc, *sm.parameters["fc"]),
        _row("Fs", "N", t1["fs"], gst.fs, *sm.parameters["fs"]),
        _row("Vs", "m/s", t1["vs_mm_s"] * 1e-3, gst.vs, *sm.parameters["vs"]),
        _row("sigma", "N s/m", t1["sigma_N_s_per_mm"] * 1e3, gms.sigma, *sm.parameters["sigma"]),
        _row("delta", "1", t1["delta"], gst.delta, *sm.parameters["delta"]),
    ]
    order = np.argsort(np.asarray(gms.break_forces) / np.asarray(gms.k))
    k_true = np.asarray(gms.k)[order]
    w_true = np.asarray(gms.break_forces)[order]
    k_printed = np.asarray(presets.PAPER_TABLE2_K_N_PER_MM)[order]
    w_printed = np.asarray(presets.PAPER_TABLE2_W_N)[order]
    truth.update({f"k{i + 1}": float(k) for i, k in enumerate(k_true)})
    truth.update({f"w{i + 1}": float(w) for i, w in enumerate(w_true)})
    rows = []
    nb = ps.info["n_blocks"]
    for i in range(len(k_true)):
        if i < nb:
            v, e = ps.parameters[f"k{i + 1}"]
            rows.append(_row(f"k{i + 1}", "N/mm", float(k_printed[i]), float(k_true[i]) * 1e-3, v * 1e-3, e * 1e-3))
    for i in range(len(w_true)):
        if i < nb:
            rows.append(_row(f"w{i + 1} (alpha_i s(0))", "N", float(w_printed[i]), float(w_true[i]), *ps.parameters[f"w{i + 1}"]))
    tables[f"Table 2: GMS blocks, ordered by break displacement (eq. 6)  [{nb} blocks; BIC-free choice: paper's 4]"] = rows
    e1 = presets.PAPER_EQ1
    truth.update({"a": plant.a, "b": plant.b, "c": plant.c, "delay": plant.delay})
    tables["Eq. 1: linear fit of the measured FRF (friction acting, so A, B, C are apparent)  [mm/(V s^2), 1/s, 1/s^2, ms]"] = [
        _row("A", "mm/(V s^2)", e1["a_mm"], plant.a * 1e3, pf.value("a") * 1e3, pf.stderr("a") * 1e3),
        _row("B", "1/s", e1["b"], plant.b, *pf.parameters["b"]),
        _row("C", "1/s^2", e1["c"], plant.c, *pf.parameters["c"]),
        _row("delay", "ms", e1["delay"] * 1e3, plant.delay * 1e3, pf.value("delay") * 1e3, pf.stderr("delay") * 1e3),
    ]
    for label, rv, printed in (("static friction model", rv_s, s.table3.static), ("GMS model", rv_g, s.table3.gms)):
        tables[f"Table 3: revised A', B', C' with the {label} in the loop (true = rig mechanics)"] = [
            _row("A'", "mm/(V s^2)", printed[0], plant.a * 1e3, rv.value("a") * 1e3, rv.stderr("a") * 1e3),
            _row("B'", "1/s", printed[1], plant.b, *rv.parameters["b"]),
            _row("C'", "1/s^2", printed[2], plant.c, *rv.parameters["c"]),
        ]
    return Replay(s, truth, sm, ps, pf, rv_s, rv_g, tables)
