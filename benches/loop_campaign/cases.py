"""The campaign's case list, generated reproducibly from one seed, and the fixed CI subset.

A case is a JSON-able dict: the simulator (``own``, ``core`` or ``emps``), the rig (SI), the
trajectories of its estimation and validation runs, the planted catalogue effects (physical
parameters in SI, ``grade`` 0-3 = weakest to strongest), effects outside the catalogue, native
effects of real data, and the file format the runs are written in (names, units, force or
command with a gain).  Groups:

=========  ======================================================================================
single     one catalogue effect at graded strengths (8 effects x 4 grades x 4-5 rigs) and ``offset``
           with the rigid baseline (``--baseline rigid``)
pair       two catalogue effects at medium to strong grades (the issue's combinations included)
outside    effects outside the catalogue: v|v| drag, backlash, a force ripple in time, a square wave
clean      nothing planted (all simulators, contacts, controllers, rates, units)
robot      rotary joints logged at 100 Hz nominal with irregular time stamps (2-18 ms steps)
emps       the real EMPS runs with effects planted on the measured force (and two unplanted)
=========  ======================================================================================
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .rigs import make_shape, position_shape

#: The catalogue effects the campaign plants (``offset`` only with the rigid baseline).
EFFECTS = (
    "asymmetric_friction", "stribeck", "presliding_hysteresis", "position_dependent_friction",
    "position_dependent_force", "input_delay", "friction_drift", "compliance",
)
CATALOGUE = EFFECTS + ("offset",)
#: Effects detectable in fewer rigs at a grade: one more rig per grade.
SCARCE = {"asymmetric_friction", "stribeck", "friction_drift", "input_delay"}
#: Effects the core simulator can plant in feedback.
CORE_EFFECTS = {"stribeck", "presliding_hysteresis", "input_delay", "offset", "ripple", "square"}

Rng = np.random.Generator


def _logu(rng: Rng, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def _pick(rng: Rng, items: list[Any] | tuple[Any, ...], p: list[float] | None = None) -> Any:
    return items[int(rng.choice(len(items), p=p))]


# ------------------------------------------------------------------------------------------
# Rigs.


def random_rig(rng: Rng, sim: str, axis: str | None = None, robot: bool = False) -> dict[str, Any]:
    """A physically plausible axis: mass, friction, travel, speeds, encoder, noise, rates, controller."""
    axis = axis or ("rotary" if robot or rng.random() < 0.35 else "linear")
    if axis == "linear":
        M, Fc, Fv = _logu(rng, 5, 150), _logu(rng, 3, 40), _logu(rng, 10, 300)
        travel, vmax = rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.3)
        quant = float(_pick(rng, [0.05e-6, 0.1e-6, 0.5e-6, 1e-6, 2e-6]))
    else:
        # friction tied to the inertia (break-away decelerates the joint at 5-200 rad/s^2)
        M, Fv = _logu(rng, 0.005, 2.0), _logu(rng, 0.05, 5.0)
        Fc = float(np.clip(M * _logu(rng, 5.0, 200.0), 0.05, 20.0))
        travel, vmax = rng.uniform(0.8, 3.0), rng.uniform(0.5, 2.5)
        quant = 2 * math.pi / 2 ** int(_pick(rng, [15, 16, 17, 18, 20]))
    if robot:
        vmax = min(vmax, 1.0)
    amax = float(np.clip(_logu(rng, 0.5, 4.0) * Fc / M, 0.3 if axis == "linear" else 1.0, 8.0 if axis == "linear" else 20.0))
    if robot:
        amax = min(amax, 3.0)
    if robot:
        fs_log, f_ctrl = 100, 1000
    else:
        fs_log = int(_pick(rng, [250, 500, 1000, 2000, 5000], [0.15, 0.2, 0.35, 0.2, 0.1]))
        f_ctrl = int(_pick(rng, [f for f in (1000, 2000, 4000, 5000) if f >= fs_log and f % fs_log == 0]))
    scale = Fc + M * amax + Fv * vmax
    rig: dict[str, Any] = {
        "axis": axis, "M": M, "Fc": Fc, "Fv": Fv, "travel": travel, "vmax": vmax, "amax": amax,
        "quant": quant, "noise": rng.uniform(0.002, 0.01) * scale, "f_ctrl": f_ctrl,
        "log_every": max(1, f_ctrl // fs_log), "jitter": "robot" if robot else ("mild" if rng.random() < 0.05 else None),
        "ulim": float(rng.uniform(0.6, 0.9) * scale) if rng.random() < 0.15 else None,
        "gain": _logu(rng, 0.5, 50.0),
        "contact": {"model": "karnopp" if sim == "own" else _pick(rng, ["static", "lugre", "gms", "maxwell"])},
    }
    kinds = ["pid", "ppi"] if sim == "own" else ["pid", "pp"]
    ctrl: dict[str, Any] = {"kind": _pick(rng, kinds), "fb": _logu(rng, 3.0, 8.0) if robot else _logu(rng, 5.0, 30.0)}
    if rng.random() < 0.6:
        ff = {"mass": M * rng.uniform(0.85, 1.15), "veps": 0.02 * vmax}
        if rng.random() < 0.5:
            ff["fv"] = Fv * rng.uniform(0.8, 1.2)
        if rng.random() < 0.4:
            ff["fc"] = Fc * rng.uniform(0.7, 1.1)
        ctrl["ff"] = ff
        ctrl["ff_vel"] = bool(rng.random() < 0.7)
    rig["ctrl"] = ctrl
    _limit_bandwidth(rig, 0.0)
    _limit_quantisation_noise(rig, sim)
    if rig["contact"]["model"] != "karnopp":
        rig["contact"] = stiff_contact(rig, rng, rig["contact"]["model"])
    return rig


def _limit_quantisation_noise(rig: dict[str, Any], sim: str) -> None:
    """A designer matches the encoder to the loop gains: one encoder count may move the command by
    at most 5 % of the axis' force scale through the velocity feedback (finer encoder otherwise)."""
    M, Tc, wb = rig["M"], 1.0 / rig["f_ctrl"], 2 * math.pi * rig["ctrl"]["fb"]
    kind = rig["ctrl"]["kind"]
    if kind == "pid":
        k_per_count = 3 * M * wb / max(Tc, 1.0 / (10 * wb))
    elif kind == "ppi":
        k_per_count = 4 * M * wb / max(Tc, 1.0 / (20 * wb))
    else:  # the core's 2-tap FIR cascade: one count is quant / (2 Tc) of velocity
        k_per_count = 4 * M * wb / (2 * Tc)
    scale = rig["Fc"] + M * rig["amax"] + rig["Fv"] * rig["vmax"]
    q_max = 0.05 * scale / k_per_count
    if rig["quant"] > q_max:
        rig["quant"] = float(max(q_max, 1e-9 if rig["axis"] == "linear" else 1e-8))


def stiff_contact(rig: dict[str, Any], rng: Rng, model: str) -> dict[str, Any]:
    """A contact whose pre-sliding is far below the encoder resolution (clean friction)."""
    delta = rig["quant"] * rng.uniform(0.05, 0.2)
    return contact(rig, rng, model, delta)


def contact(rig: dict[str, Any], rng: Rng, model: str, delta: float) -> dict[str, Any]:
    """Contact spec with characteristic break displacement ``delta`` (m or rad) at level Fc."""
    Fc = rig["Fc"]
    if model == "static":
        return {"model": "static"}
    if model == "lugre":
        s0 = Fc / delta
        return {"model": "lugre", "fc": Fc, "sigma0": s0, "sigma1": math.sqrt(s0 * rig["M"])}
    frac = np.array([0.5, 0.3, 0.2])
    brk = delta * np.array([0.3, 1.0, 3.0]) * rng.uniform(0.7, 1.4, 3)
    w = Fc * frac
    k = w / brk
    if model == "gms":
        return {"model": "gms", "fc": Fc, "k": k.tolist(), "alpha": frac.tolist(), "c": 500.0 * Fc}
    return {"model": "maxwell", "k": k.tolist(), "w": w.tolist()}


def _limit_bandwidth(rig: dict[str, Any], tau: float) -> None:
    """Keep the loop bandwidth below what the controller rate and the delay allow: the innermost
    crossover (velocity loop at 4 fb for the cascades, ~2 fb for the PID) loses at most ~0.3 rad
    of phase to the delay plus one sample."""
    inner = 2.0 if rig["ctrl"]["kind"] == "pid" else 4.0
    f_max = min(rig["f_ctrl"] / 50.0, 0.3 / (2 * math.pi * inner * (tau + 1.0 / rig["f_ctrl"])))
    rig["ctrl"]["fb"] = float(min(rig["ctrl"]["fb"], f_max))


def _drive_limit(case: dict[str, Any]) -> None:
    """A saturating drive must still hold the axis: the limit exceeds 1.5x the largest static
    force (break-away level, position-dependent force, constant and disturbance forces)."""
    rig = case["rig"]
    if rig.get("ulim") is None:
        return
    q = np.linspace(-0.6, 0.6, 401) * rig["travel"]
    need = rig["Fc"]
    for e in case["effects"] + case["outside"]:
        if e["name"] == "stribeck":
            need += e["dF"]
        elif e["name"] == "asymmetric_friction":
            need += abs(e.get("dFc", 0.0))
        elif e["name"] in ("position_dependent_force", "position_dependent_friction"):
            need += float(np.max(np.abs(position_shape(q, np.asarray(e["shape"])))))
        elif e["name"] == "friction_drift":
            need += abs(e["dF"]) * (1.0 if e["kind"] == 0 else case["duration"] / e["T"])
        elif e["name"] == "offset":
            need += abs(e["f0"])
        elif e["name"] in ("ripple", "square"):
            need += e["amp"]
    rig["ulim"] = float(max(rig["ulim"], 1.5 * need + 0.5 * rig["Fv"] * rig["vmax"]))


def trajectories(rng: Rng, rig: dict[str, Any], robot: bool = False) -> dict[str, dict[str, Any]]:
    out = {}
    for which in ("est", "val"):
        kind = _pick(rng, ["trapezoid", "sweep", "random", "mixed"], [0.2, 0.3, 0.3, 0.2])
        spec: dict[str, Any] = {"kind": kind, "seed": int(rng.integers(2**31)), "travel": rig["travel"], "vmax": rig["vmax"], "amax": rig["amax"]}
        if robot:
            spec["f_hi"] = rng.uniform(1.0, 2.0)
        out[which] = spec
    return out


# ------------------------------------------------------------------------------------------
# Effects at graded strengths (physical parameters in SI).

#: Relative strength per grade 0..3 (the scale each effect's amplitude is relative to is below).
GRADES = {
    "asymmetric_friction": (0.05, 0.15, 0.35, 0.7),        # dFv / Fv
    "stribeck": (0.1, 0.25, 0.6, 1.2),                     # (Fs - Fc) / Fc
    "presliding_hysteresis": (0.1, 0.5, 3.0, 20.0),        # break displacement / encoder step
    "position_dependent_friction": (0.04, 0.1, 0.25, 0.6),  # friction change / Fc
    "position_dependent_force": (0.03, 0.1, 0.3, 1.0),     # force amplitude / Fc
    "input_delay": (0.2, 0.6, 1.5, 4.0),                   # delay (ms)
    "friction_drift": (0.05, 0.15, 0.35, 0.7),             # friction change over the run / Fc
    "compliance": (0.03, 0.1, 0.3, 0.8),                   # load mass / motor mass
    "offset": (0.02, 0.06, 0.2, 0.6),                      # constant force / Fc
}


def effect(name: str, grade: int, rig: dict[str, Any], rng: Rng, duration: float) -> dict[str, Any]:
    """Physical parameters of a planted catalogue effect at a grade on a rig."""
    s = GRADES[name][grade] * rng.uniform(0.8, 1.25)
    Fc, Fv, L, vmax = rig["Fc"], rig["Fv"], rig["travel"], rig["vmax"]
    e: dict[str, Any] = {"name": name, "grade": grade}
    if name == "asymmetric_friction":
        e["dFv"] = s * Fv * float(_pick(rng, [1.0, -1.0]))
        if rig["contact"]["model"] == "karnopp" and rng.random() < 0.35:
            e["dFc"] = rng.uniform(0.1, 0.3) * Fc * float(_pick(rng, [1.0, -1.0]))
    elif name == "stribeck":
        kind = 1 if rig["contact"]["model"] == "karnopp" and rng.random() < 0.35 else 0
        e.update(dF=s * Fc, vs=vmax * _logu(rng, 0.02, 0.15), kind=kind, delta=float(_pick(rng, [0.7, 1.0, 2.0])) if kind == 0 else 2.0)
    elif name == "presliding_hysteresis":
        pass  # the rig's contact carries the parameters (see plant())
    elif name == "position_dependent_friction":
        form = _pick(rng, ["gradient", "bump", "lead"])
        B = s * Fc
        if form == "gradient":
            e["shape"] = make_shape(lin=(2 * B / L * float(_pick(rng, [1.0, -1.0])), rng.uniform(-0.1, 0.1) * L))
        elif form == "bump":
            e["shape"] = make_shape(bumps=[(B * float(_pick(rng, [1.0, -0.6])), rng.uniform(-0.25, 0.25) * L, L * rng.uniform(0.06, 0.2))])
        else:
            e["shape"] = make_shape(sines=[(B, L * rng.uniform(0.08, 0.3), rng.uniform(0, 2 * math.pi))])
        e["form"] = form
    elif name == "position_dependent_force":
        A = s * Fc
        forms = ["cogging", "spring", "cable"] + (["gravity"] if rig["axis"] == "rotary" else [])
        form = _pick(rng, forms)
        if form == "cogging":
            p = L * rng.uniform(0.03, 0.2)
            sines = [(A, p, rng.uniform(0, 2 * math.pi))]
            if rng.random() < 0.4:
                sines.append((0.4 * A, p / 2, rng.uniform(0, 2 * math.pi)))
            e["shape"] = make_shape(sines=sines)
        elif form == "spring":
            e["shape"] = make_shape(lin=(-2 * A / L, rng.uniform(-0.3, 0.3) * L))
        elif form == "cable":
            e["shape"] = make_shape(tanh=(A, rng.uniform(-0.2, 0.2) * L, L * rng.uniform(0.1, 0.3)))
        else:
            e["shape"] = make_shape(grav=(-A, rng.uniform(-0.5, 0.5)))
        e["form"] = form
    elif name == "input_delay":
        e["tau"] = float(min(s * 1e-3, 6e-3))
    elif name == "friction_drift":
        kind = int(rng.random() < 0.3)
        e.update(kind=kind, dF=s * Fc, T=duration if kind == 1 else duration * rng.uniform(0.12, 0.4))
        if rng.random() < 0.4:
            e["dFv"] = s * Fv * rng.uniform(0.3, 1.0)
    elif name == "compliance":
        m2 = s * rig["M"]
        f2 = rng.uniform(4.0, 30.0) if rig.get("jitter") != "robot" else rng.uniform(1.5, 4.0)
        z2 = rng.uniform(0.03, 0.2)
        k2 = m2 * (2 * math.pi * f2) ** 2
        e.update(m2=m2, k2=k2, c2=2 * z2 * math.sqrt(k2 * m2))
    elif name == "offset":
        e["f0"] = s * Fc * float(_pick(rng, [1.0, -1.0]))
    return e


def outside_effect(kind: str, strong: bool, rig: dict[str, Any], rng: Rng) -> dict[str, Any]:
    """An effect outside the catalogue (nothing should be added for it)."""
    Fc, M, L, vmax = rig["Fc"], rig["M"], rig["travel"], rig["vmax"]
    s = (0.8 if strong else 0.3) * rng.uniform(0.8, 1.25)
    if kind == "drag":
        return {"name": "drag", "c2": s * Fc / vmax**2}
    if kind == "backlash":
        m2 = rng.uniform(0.2, 0.6) * M
        f2 = rng.uniform(10, 40)
        k2 = m2 * (2 * math.pi * f2) ** 2
        gap = rig["quant"] * (_logu(rng, 20, 200) if rig["axis"] == "linear" else _logu(rng, 5, 50))
        return {"name": "backlash", "m2": m2, "k2": k2, "c2": 2 * 0.1 * math.sqrt(k2 * m2), "gap": gap, "b2": 0.05 * rig["Fv"]}
    if kind == "ripple":
        return {"name": "ripple", "amp": s * 0.5 * Fc, "freq": rng.uniform(1.0, 15.0)}
    if kind == "square":
        return {"name": "square", "amp": s * 0.5 * Fc, "freq": rng.uniform(0.05, 0.4)}
    raise ValueError(kind)


def _file_format(rng: Rng, rig: dict[str, Any], robot: bool = False) -> dict[str, Any]:
    ext = "mat" if rng.random() < 0.4 else "csv"
    names = _pick(rng, [("t", "q", "f", "u"), ("time", "position", "force", "command"), ("timestamp", "pos", "tau", "cmd"), ("T", "x", "F", "vir")])
    if rig["axis"] == "rotary":
        pu = _pick(rng, ["rad", "deg"], [0.7, 0.3])
        fu = _pick(rng, ["Nm", "N"])
    else:
        pu = _pick(rng, ["m", "mm", "um"], [0.5, 0.3, 0.2])
        fu = _pick(rng, ["N", "mN", "kN"], [0.75, 0.15, 0.1])
    fmt: dict[str, Any] = {
        "ext": ext, "cols": dict(zip(("time", "position", "force", "command"), names)),
        "time_unit": "ms" if rng.random() < 0.15 else "s", "position_unit": pu, "force_unit": fu,
    }
    if rng.random() < 0.3 and not robot:
        fmt["command"] = True
        fmt["gain"] = rig["gain"]
        if ext == "mat" and rng.random() < 0.6:
            fmt["gain_name"] = _pick(rng, ["kt", "gtau", "drive_gain"])
    return fmt


def plant(case: dict[str, Any], rng: Rng) -> None:
    """Make the rig carry what its planted effects need (contact, delay-limited bandwidth)."""
    rig = case["rig"]
    names = {e["name"] for e in case["effects"]}
    pre = next((e for e in case["effects"] if e["name"] == "presliding_hysteresis"), None)
    if pre is not None:
        model = "maxwell" if case["sim"] == "own" else ("gms" if "stribeck" in names or rng.random() < 0.6 else "maxwell")
        delta = GRADES["presliding_hysteresis"][pre["grade"]] * rig["quant"] * rng.uniform(0.8, 1.25)
        c = contact(rig, rng, model, delta)
        rig["contact"] = c
        pre.update({k: v for k, v in c.items()})
    elif "stribeck" in names and rig["contact"]["model"] == "maxwell":
        rig["contact"] = stiff_contact(rig, rng, _pick(rng, ["static", "lugre", "gms"]))  # Maxwell-slip has no Stribeck curve
    if rig["contact"]["model"] != "karnopp":
        for e in case["effects"]:
            e.pop("dFc", None)  # a Coulomb asymmetry needs the Karnopp contact
    tau = next((e["tau"] for e in case["effects"] if e["name"] == "input_delay"), 0.0)
    _limit_bandwidth(rig, tau)
    _drive_limit(case)


def _sim_for(names: set[str], rng: Rng) -> str:
    if names <= CORE_EFFECTS and rng.random() < 0.5:
        return "core"
    return "own"


def make_case(group: str, idx: int, rng: Rng, effects: list[tuple[str, int]], outside: Sequence[tuple[str, bool]] = (),
              sim: str | None = None, robot: bool = False, baseline: str = "reference", axis: str | None = None) -> dict[str, Any]:
    """One simulated case: a random rig with the given planted effects (name, grade)."""
    names = {n for n, _ in effects} | {n for n, _ in outside}
    sim = sim or ("own" if robot else _sim_for(names, rng))
    if "presliding_hysteresis" in names and "stribeck" in names:
        sim = "core"  # a GMS contact carries both
    rig = random_rig(rng, sim, axis=axis, robot=robot)
    duration = float(rng.uniform(12.0, 20.0)) if not robot else float(rng.uniform(25.0, 30.0))
    label = "+".join(n for n, _ in effects) or ("+".join(n for n, _ in outside) or "clean")
    case: dict[str, Any] = {
        "id": f"{group}-{idx:03d}-{label}", "group": group, "seed": int(rng.integers(2**31)), "sim": sim,
        "duration": duration, "baseline": baseline, "rig": rig, "traj": trajectories(rng, rig, robot),
        "effects": [effect(n, gr, rig, rng, duration) for n, gr in effects],
        "outside": [outside_effect(n, strong, rig, rng) for n, strong in outside], "native": [],
    }
    if not effects and sim == "own" and rng.random() < 0.3:
        rig["contact"] = stiff_contact(rig, rng, "maxwell")
    plant(case, rng)
    case["fmt"] = _file_format(rng, rig, robot)
    return case


# ------------------------------------------------------------------------------------------
# EMPS.

EMPS_FILES = {"forward": {"est": "DATA_EMPS.mat", "val": "DATA_EMPS_PULSES.mat"},
              "swapped": {"est": "DATA_EMPS_PULSES.mat", "val": "DATA_EMPS.mat"}}
#: Effects the real EMPS axis has of its own (``emps_native.py`` measures them by the campaign's
#: detectability rule on the unmodified runs): a viscous asymmetry (Fv ~171 N s/m in +q, ~245 in
#: -q) and a low-speed friction dip (Lorentzian, ~12.6 mm/s wide; held-out gain 12 % and 16 % in
#: the two directions).  Accepting them there is not false, and the true model includes them.
EMPS_NATIVE = [{"name": "asymmetric_friction", "dFv": 1.0},
               {"name": "stribeck", "vs": 0.0126, "kind": 1, "delta": 2.0}]


def emps_cases(rng: Rng, start: int = 0) -> list[dict[str, Any]]:
    """Effects planted on the real EMPS force ``gtau * vir`` (travel 0-0.25 m, |v| <= 0.125 m/s)."""
    L = 0.246
    specs: list[dict[str, Any] | None] = []
    # (10 N, 10 mm/s, Gaussian) is the issue's "strong low-speed hump" (4.03 -> 4.34 % estimation error)
    for dF, vs, kind, delta in [(4, 0.01, 0, 2.0), (8, 0.02, 0, 2.0), (10, 0.01, 0, 2.0), (14, 0.005, 0, 2.0),
                                (16, 0.01, 1, 2.0), (20, 0.02, 0, 1.0), (24, 0.01, 0, 2.0), (30, 0.005, 0, 1.0)]:
        specs.append({"name": "stribeck", "dF": float(dF), "vs": vs, "kind": kind, "delta": delta})
    for A, p in [(0.5, 0.008), (1.0, 0.016), (2.0, 0.04), (4.0, 0.004)]:
        specs.append({"name": "position_dependent_force", "form": "cogging", "shape": make_shape(sines=[(A, p, rng.uniform(0, 2 * math.pi))])})
    specs.append({"name": "position_dependent_force", "form": "spring", "shape": make_shape(lin=(-30.0, 0.12))})
    specs.append({"name": "position_dependent_force", "form": "cable", "shape": make_shape(tanh=(3.0, 0.1, 0.04))})
    for B, form in [(1.0, "bump"), (2.0, "gradient"), (4.0, "lead"), (6.0, "bump"), (8.0, "gradient")]:
        if form == "bump":
            shape = make_shape(bumps=[(B, rng.uniform(0.05, 0.2), 0.02)])
        elif form == "gradient":
            shape = make_shape(lin=(2 * B / L, 0.12))
        else:
            shape = make_shape(sines=[(B, 0.05, rng.uniform(0, 2 * math.pi))])
        specs.append({"name": "position_dependent_friction", "form": form, "shape": shape})
    for level, T, law in [(1.0, 8.0, 0), (2.0, 5.0, 0), (4.0, 25.0, 1), (6.0, 10.0, 0), (3.0, 25.0, 1)]:
        specs.append({"name": "friction_drift", "dF": level, "T": T, "kind": law})
    for W, d in [(2.0, 20e-6), (5.0, 50e-6), (10.0, 20e-6), (15.0, 100e-6)]:
        brk = d * np.array([0.3, 1.0, 3.0])
        w = W * np.array([0.5, 0.3, 0.2])
        specs.append({"name": "presliding_hysteresis", "model": "maxwell", "k": (w / brk).tolist(), "w": w.tolist()})
    for tau in (1e-3, 2e-3, 4e-3):
        specs.append({"name": "input_delay", "tau": tau})
    for m2, f2, z2 in [(5.0, 8.0, 0.05), (15.0, 15.0, 0.1), (40.0, 25.0, 0.08)]:
        k2 = m2 * (2 * math.pi * f2) ** 2
        specs.append({"name": "compliance", "m2": m2, "k2": k2, "c2": 2 * z2 * math.sqrt(k2 * m2)})
    specs += [None, None]
    cases = []
    for i, spec in enumerate(specs):
        direction = "swapped" if (spec is None and i == len(specs) - 1) or (spec is not None and rng.random() < 0.25) else "forward"
        label = spec["name"] if spec else "clean"
        fmt: dict[str, Any] = {"ext": "mat", "cols": {"time": "t", "position": "qm", "force": "force", "command": "vir"},
                               "time_unit": "s", "position_unit": "m", "force_unit": "N"}
        if rng.random() < 0.5:
            fmt.update(command=True, gain=35.15065188, gain_name="gtau")
        cases.append({
            "id": f"emps-{start + i:03d}-{label}", "group": "emps", "seed": int(rng.integers(2**31)), "sim": "emps",
            "baseline": "reference", "files": EMPS_FILES[direction], "direction": direction,
            "effects": [dict(spec, grade=None)] if spec else [], "outside": [], "native": EMPS_NATIVE, "fmt": fmt,
        })
    return cases


# ------------------------------------------------------------------------------------------
# The campaign.

#: Pairs the issue saw fail, planted on purpose (the rest of the pairs are random).
ISSUE_PAIRS = [("asymmetric_friction", "position_dependent_force")] * 4 + [
    ("position_dependent_force", "position_dependent_friction")] * 2 + [
    ("presliding_hysteresis", "compliance")] * 2 + [("compliance", "input_delay")] * 2


def make_cases(seed: int = 2024, emps: bool = True) -> list[dict[str, Any]]:
    """The full campaign (about 310 cases), deterministic for a seed."""
    rng = np.random.default_rng(seed)
    cases: list[dict[str, Any]] = []
    i = 0
    for name in EFFECTS:
        for grade in range(4):
            for _ in range(5 if name in SCARCE else 4):
                cases.append(make_case("single", i, rng, [(name, grade)]))
                i += 1
    for grade in range(4):
        for _ in range(2):
            cases.append(make_case("single", i, rng, [("offset", grade)], baseline="rigid"))
            i += 1
    pairs = list(ISSUE_PAIRS)
    while len(pairs) < 44:
        a, b = rng.choice(len(EFFECTS), 2, replace=False)
        pairs.append((EFFECTS[a], EFFECTS[b]))
    for a, b in pairs:
        cases.append(make_case("pair", i, rng, [(a, int(rng.integers(1, 4))), (b, int(rng.integers(1, 4)))]))
        i += 1
    for kind in ("drag", "backlash", "ripple", "square"):
        for k in range(7):
            cases.append(make_case("outside", i, rng, [], [(kind, k % 2 == 1)]))
            i += 1
    for k in range(52):
        base = "rigid" if k < 4 else "reference"
        cases.append(make_case("clean", i, rng, [], baseline=base))
        i += 1
    robot_effects: list[list[tuple[str, int]]] = [[]] * 6 + [[(n, 3)] for n in (
        "position_dependent_force", "asymmetric_friction", "stribeck", "friction_drift", "position_dependent_friction",
        "compliance", "presliding_hysteresis", "input_delay")] + [[("position_dependent_force", 2)], [("asymmetric_friction", 2)]]
    for effs in robot_effects:
        cases.append(make_case("robot", i, rng, effs, robot=True))
        i += 1
    if emps:
        cases += emps_cases(rng, start=i)
    return cases


#: The CI subset: (planted effects, case options, rng seed).  The seeds were picked, by looking at
#: the ground truth only (never at the loop), so that every planted effect is detectable with a
#: margin (gain >= 0.25 with and without standstill rows) and the clean runs are clean (held-out
#: baseline error < 6 %, contact pre-sliding invisible).  A change to the generator changes them.
CI_PLAN: list[tuple[list[tuple[str, int]], dict[str, Any], int]] = [
    ([], {"sim": "own", "axis": "linear"}, 0),
    ([], {"sim": "core", "axis": "rotary"}, 1),
    ([("stribeck", 3)], {"sim": "own", "axis": "linear"}, 1),
    ([("position_dependent_force", 3)], {"sim": "own", "axis": "rotary"}, 0),
    ([("asymmetric_friction", 3)], {"sim": "own", "axis": "linear"}, 3),
    ([("presliding_hysteresis", 3)], {"sim": "core", "axis": "linear"}, 0),
    ([("input_delay", 3)], {"sim": "core", "axis": "linear"}, 0),
    ([("compliance", 3)], {"sim": "own", "axis": "linear"}, 0),
    ([("friction_drift", 3)], {"sim": "own", "axis": "linear"}, 0),
    ([("position_dependent_friction", 3)], {"sim": "own", "axis": "rotary", "robot": True}, 2),
]


def ci_case(k: int, seed: int | None = None) -> dict[str, Any]:
    """CI case ``k`` of :data:`CI_PLAN` (10 s at 1 kHz, or a 20 s jittered robot log)."""
    effs, kw, s = CI_PLAN[k]
    rng = np.random.default_rng(1000 * k + (s if seed is None else seed))
    c = make_case("ci", k, rng, effs, **kw)
    rig = c["rig"]
    if not kw.get("robot"):
        rig.update(f_ctrl=1000, log_every=1, jitter=None)
        c["duration"] = 10.0
        plant(c, rng)
    else:
        c["duration"] = 20.0
    return c


def ci_cases() -> list[dict[str, Any]]:
    """Ten fixed small cases: two clean runs, seven strong single effects, one jittered robot log."""
    return [ci_case(k) for k in range(len(CI_PLAN))]
