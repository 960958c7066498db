"""Virtual test rigs: a closed-loop axis on the compiled core with one planted effect.

Each rig runs a cascade-controlled rigid axis (mass, drive gain, viscous + Coulomb friction and
an offset: the loop's baseline structure) on a random smooth trajectory with a small chirp
for excitation, with encoder quantisation and force-sensor noise, and plants at most one
catalogue effect.  Effects the core simulates natively (Stribeck, GMS pre-sliding, input
delay, heating) are exact; the others act as a load force computed along the simulated trajectory and
iterated to a fixed point (the trajectory moves by nanometres between iterations).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy import signal

from ..models import GMS, StaticFriction, Stribeck
from ..system import Cascade, Plant, simulate_closed_loop
from .data import AxisData

PLANTABLE = (
    "asymmetric_friction",
    "stribeck",
    "presliding_hysteresis",
    "position_dependent_friction",
    "position_dependent_force",
    "input_delay",
    "friction_drift",
    "compliance",
    "heating",
)


@dataclass(frozen=True)
class Rig:
    """Parameters of a virtual rig (SI).  ``effect=None`` is the clean rig."""

    effect: str | None = None
    mass: float = 60.0
    gain: float = 30.0
    fv: float = 150.0
    fc: float = 15.0
    offset: float = -2.0
    fs: float = 1000.0
    duration: float = 24.0
    travel: float = 0.15
    quantization: float = 1e-6
    force_noise: float = 0.3
    strength: float = 1.0
    seed: int = 0

    def controller(self) -> Cascade:
        return Cascade(kp=160.0, kv=2.56 * self.mass, u_min=-1e3, u_max=1e3)


def _trajectory(rig: Rig, rng: np.random.Generator) -> np.ndarray:
    n = int(round(rig.duration * rig.fs))
    t = np.arange(n) / rig.fs
    q = np.zeros(n)
    for _ in range(4):
        f = rng.uniform(0.08, 0.6)
        q += rng.uniform(0.3, 1.0) * np.sin(2 * np.pi * f * t + rng.uniform(0, 2 * np.pi))
    q = (q - q.min()) / np.ptp(q) * rig.travel
    f_hi = min(20.0, rig.fs / 40)
    chirp = signal.chirp(t, 1.0, t[-1], f_hi, method="logarithmic")
    q += 2e-4 * rig.travel / 0.15 * chirp * np.sin(np.pi * t / t[-1]) ** 2
    ramp = np.clip(t / 0.5, 0, 1)
    return q[0] + (q - q[0]) * ramp


def _extra_force(rig: Rig, t: np.ndarray, q: np.ndarray, v: np.ndarray, a: np.ndarray) -> np.ndarray:
    s = rig.strength
    e = rig.effect
    lo, hi = float(q.min()), float(q.max())
    if e == "asymmetric_friction":
        return s * 0.3 * rig.fv * np.abs(v)
    if e == "position_dependent_force":
        period = (hi - lo) / 6.3
        return s * 0.35 * rig.fc * np.sin(2 * np.pi * q / period) + s * 0.2 * rig.fc * (q - lo) / (hi - lo)
    if e == "position_dependent_friction":
        x = (q - lo) / (hi - lo)
        return s * 0.4 * rig.fc * (np.cos(np.pi * x) + 0.5 * np.sin(3 * np.pi * x)) * np.sign(v)
    if e == "friction_drift":
        h = np.exp(-t / (0.25 * t[-1]))
        return s * h * (0.5 * rig.fc * np.sign(v) + 0.25 * rig.fv * v)
    if e == "compliance":
        fn, zeta, m2 = 14.0, 0.1, s * 0.25 * rig.mass
        w = 2 * np.pi * fn
        b, aa = signal.bilinear([-1.0, 0.0, 0.0], [1.0, 2 * zeta * w, w * w], fs=rig.fs)
        return m2 * signal.lfilter(b, aa, a)
    return np.zeros_like(q)


def simulate_rig(rig: Rig) -> AxisData:
    """Run the rig and return the measured data (encoder position, ``gain * command`` force
    with sensor noise, reference).

    Returns
    -------
    AxisData
        ``meta`` holds the planted effect's index in :data:`PLANTABLE` (or -1).
    """
    rng = np.random.default_rng(rig.seed)
    ref = _trajectory(rig, rng)
    dt = 1.0 / rig.fs
    s = rig.strength
    delay = 0.003 * s if rig.effect == "input_delay" else 0.0
    plant = Plant.from_mass(rig.mass, force_gain=rig.gain, delay=delay)
    offset_force = np.full(ref.size, rig.offset)
    if rig.effect == "stribeck":
        fr = StaticFriction(Stribeck(rig.fc, rig.fc * (1 + 0.8 * s), 0.02 * rig.travel / 0.15 * 0.5), sigma=rig.fv, offset=rig.offset)
    elif rig.effect == "presliding_hysteresis":
        w = np.array([0.5, 0.3, 0.2])
        k = rig.fc * w / (np.array([20e-6, 80e-6, 300e-6]) * s)
        fr = GMS(Stribeck(rig.fc, rig.fc, 1.0), k=list(k), alpha=list(w), c=200.0 * rig.fc, sigma=rig.fv)
        offset_force = offset_force  # GMS has no offset: it goes to the load
    else:
        fr = StaticFriction(Stribeck(rig.fc, rig.fc, 1.0), sigma=rig.fv, offset=rig.offset)
    if rig.effect == "heating":
        return _simulate_heating(rig, ref, fr, rng)
    load = offset_force if rig.effect == "presliding_hysteresis" else np.zeros(ref.size)
    extra = np.zeros(ref.size)
    for _ in range(4 if rig.effect in ("asymmetric_friction", "position_dependent_force", "position_dependent_friction", "friction_drift", "compliance") else 1):
        res = simulate_closed_loop(plant, fr, rig.controller(), ref, dt, load_force=load + extra, quantization=rig.quantization)
        t = res.t
        v = res.velocity
        a = np.gradient(v, dt)
        extra = _extra_force(rig, t, res.position, v, a)
    f = rig.gain * res.command + rng.normal(0.0, rig.force_noise, ref.size)
    idx = PLANTABLE.index(rig.effect) if rig.effect else -1
    return AxisData(t=res.t, position=res.measured, force=f, source=f"rig[{rig.effect or 'clean'}, seed {rig.seed}, {rig.fs:g} Hz]",
                    command=f / rig.gain, gain=rig.gain, reference=ref, meta={"planted": float(idx)})


def _simulate_heating(rig: Rig, ref: np.ndarray, friction: StaticFriction, rng: np.random.Generator) -> AxisData:
    """Friction that follows the recent motion, simulated in feedback by the core (an
    :class:`~gmsfric.axis.AxisModel` with a heating effect).  The motion alternates between
    brisk and gentle phases, so the heating is not a function of time alone (unlike a drift)."""
    from ..axis import AxisModel, Effects, Heating

    dt = 1.0 / rig.fs
    t = np.arange(ref.size) * dt
    envelope = 0.3 + 0.7 * np.sin(np.pi * t / (0.4 * rig.duration)) ** 2
    ref = ref[0] + (ref - ref[0]) * envelope
    v_typ = 0.1 * rig.travel / 0.15  # about the mean speed of the rig's trajectories
    heat = Heating(tau=3.0, d_level=-0.5 * rig.strength * rig.fc / v_typ, d_viscous=-0.3 * rig.strength * rig.fv / v_typ)
    axis = AxisModel(Plant.from_mass(rig.mass, force_gain=rig.gain), friction, Effects(heating=heat))
    res = axis.simulate(dt, reference=ref, controller=rig.controller(), quantization=rig.quantization)
    assert res.command is not None
    f = rig.gain * res.command + rng.normal(0.0, rig.force_noise, ref.size)
    return AxisData(t=res.t, position=res.measured, force=f, source=f"rig[heating, seed {rig.seed}, {rig.fs:g} Hz]",
                    command=f / rig.gain, gain=rig.gain, reference=ref, meta={"planted": float(PLANTABLE.index("heating"))})


def rig_pair(rig: Rig) -> tuple[AxisData, AxisData]:
    """An estimation run and a validation run (another trajectory) of the same rig."""
    return simulate_rig(rig), simulate_rig(replace(rig, seed=rig.seed + 1000))
