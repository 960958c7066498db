"""Virtual rig: the paper's experiments run on the Rust simulator, with sensor noise and encoder
quantisation, so identification can be round-tripped against known parameters.

Sensors of the rig (all documented choices, all arguments):

* position: true position + white noise (``position_noise``), quantised to ``encoder``;
* force: the friction force acting on the axis plus white noise (``force_noise``), i.e. what an
  ideal inverse-dynamics estimate or a force sensor in series would give
  (``force_channel="friction"``); or ``force_gain * command`` (``"command"``), which equals the
  friction at constant velocity only for a plant without stiffness/damping terms;
* the drive command is recorded exactly (it is computed by the DSP).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy import signal

from .._validate import non_negative, positive
from ..errors import InvalidInputError
from ..models import FrictionModel, simulate_friction
from ..system import Controller, Plant, simulate_closed_loop

Columns = dict[str, NDArray[np.float64]]


def quantize(x: NDArray[np.float64], q: float) -> NDArray[np.float64]:
    """Round to multiples of ``q`` (no-op for ``q == 0``)."""
    return x if q <= 0 else np.round(x / q) * q


def band_limited_noise(n: int, dt: float, rms: float, band: tuple[float, float], rng: np.random.Generator, order: int = 4) -> NDArray[np.float64]:
    """Gaussian noise band-passed to ``band`` (Hz) (zero-phase Butterworth), scaled to ``rms``."""
    nyq = 0.5 / dt
    lo, hi = band
    if not 0 <= lo < hi:
        raise InvalidInputError(f"`band` must be (low, high) with 0 <= low < high, got {band}")
    white = rng.standard_normal(n)
    hi = min(hi, 0.95 * nyq)
    if lo > 0:
        sos = signal.butter(order, [lo / nyq, hi / nyq], btype="bandpass", output="sos")
    else:
        sos = signal.butter(order, hi / nyq, btype="lowpass", output="sos")
    u = signal.sosfiltfilt(sos, white)
    return u * (rms / max(float(np.std(u)), 1e-300))


@dataclass(frozen=True)
class VirtualRig:
    """A simulated servo axis with sensors.

    Parameters
    ----------
    plant : Plant
        Mechanics and drive (eq. 1 with delay and ``force_gain``).
    friction : friction model
        The "true" friction of the rig.
    controller : PID, Cascade or None
        Position controller for the closed-loop experiments (``None``: an open-loop rig, for the
        sinusoid and open-loop noise tests only).
    dt : float
        Sample / control period (s).
    encoder : float
        Encoder quantum (m); 0 = none.
    position_noise, force_noise : float
        Standard deviations of white sensor noise (m, N).
    force_channel : {"friction", "command"}
        What the force sensor reads (see the module docstring).
    drive_limit : float, optional
        Symmetric drive saturation.
    """

    plant: Plant
    friction: FrictionModel | None
    controller: Controller | None
    dt: float = 1e-3
    encoder: float = 0.0
    position_noise: float = 0.0
    force_noise: float = 0.0
    force_channel: Literal["friction", "command"] = "friction"
    drive_limit: float | None = None

    def __post_init__(self) -> None:
        positive("dt", self.dt)
        non_negative("encoder", self.encoder)
        non_negative("position_noise", self.position_noise)
        non_negative("force_noise", self.force_noise)
        if self.force_channel not in ("friction", "command"):
            raise InvalidInputError(f"`force_channel` must be 'friction' or 'command', got {self.force_channel!r}")

    def with_(self, **changes: object) -> "VirtualRig":
        """A copy with some fields changed."""
        return replace(self, **changes)  # type: ignore[arg-type]

    # -- sensors ------------------------------------------------------------------------------
    def _measure_position(self, x: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        noisy = x + (self.position_noise * rng.standard_normal(x.size) if self.position_noise > 0 else 0.0)
        return quantize(noisy, self.encoder)

    def _measure_force(self, f: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.float64]:
        return f + (self.force_noise * rng.standard_normal(f.size) if self.force_noise > 0 else 0.0)

    def _run(self, reference: NDArray[np.float64], rng: np.random.Generator, **kw: object):  # type: ignore[no-untyped-def]
        noise = self.position_noise * rng.standard_normal(reference.size) if self.position_noise > 0 else None
        return simulate_closed_loop(
            self.plant, self.friction, self.controller, reference, self.dt,
            measurement_noise=noise, quantization=self.encoder, drive_limit=self.drive_limit, **kw,  # type: ignore[arg-type]
        )

    # -- experiments --------------------------------------------------------------------------
    def constant_velocity_run(
        self,
        velocities: Sequence[float],
        *,
        min_time: float = 1.0,
        min_travel: float = 0.0,
        max_travel: float = np.inf,
        dwell: float = 0.3,
        seed: int | None = None,
    ) -> Columns:
        """Ramps of the reference at each speed, forward then back (paper Section 3.1, Fig. 4).

        Each plateau lasts ``max(min_time, min_travel / v)`` but travels at most ``max_travel``
        (a plant with a stiffness term needs a growing drive to hold a growing position); the
        axis dwells ``dwell`` s between ramps.  Returns columns ``t, position, force, command, reference, velocity_true``.
        """
        if self.controller is None:
            raise InvalidInputError("constant-velocity runs need a position controller: the rig's `controller` is None")
        rng = np.random.default_rng(seed)
        dt = self.dt
        pieces = [np.zeros(int(round(dwell / dt)))]
        for v in velocities:
            v = positive("velocities", abs(float(v)))
            T = min(max(min_time, min_travel / v), max_travel / v)
            n = int(round(T / dt))
            ramp = v * dt * np.arange(1, n + 1)
            base = pieces[-1][-1] if pieces[-1].size else 0.0
            pieces.append(base + ramp)
            pieces.append(np.full(int(round(dwell / dt)), pieces[-1][-1]))
            pieces.append(pieces[-1][-1] - ramp)
            pieces.append(np.full(int(round(dwell / dt)), pieces[-1][-1]))
        ref = np.concatenate(pieces)
        r = self._run(ref, rng)
        if self.force_channel == "friction":
            f = r.friction
        else:
            f = self.plant.force_gain * r.command
        return {
            "t": r.t,
            "position": self._measure_position(r.position, rng),
            "force": self._measure_force(f, rng),
            "command": r.command,
            "reference": ref,
            "velocity_true": r.velocity,
        }

    def sinusoid_test(
        self,
        amplitudes: Sequence[float],
        frequency: float,
        *,
        cycles: int = 3,
        seed: int | None = None,
    ) -> Columns:
        """Displacement-controlled sinusoids at one frequency, one amplitude after the other
        (paper Section 3.2, Fig. 6), starting from the virgin state.

        The motion follows the reference exactly (a stiff position loop); the friction force is
        simulated with the rig's model.  Returns ``t, position, force, position_true,
        force_true``.
        """
        rng = np.random.default_rng(seed)
        frequency = positive("frequency", frequency)
        n_cycle = int(round(1.0 / (frequency * self.dt)))
        xs = []
        for a in amplitudes:
            a = positive("amplitudes", a)
            k = np.arange(n_cycle * cycles)
            xs.append(a * np.sin(2 * np.pi * k / n_cycle))
        x = np.concatenate(xs + [np.zeros(1)])
        t = np.arange(x.size) * self.dt
        if self.friction is None:
            raise InvalidInputError("the rig has no friction model")
        f = simulate_friction(self.friction, t, x)
        return {"t": t, "position": self._measure_position(x, rng), "force": self._measure_force(f, rng), "position_true": x, "force_true": f}

    def noise_test(
        self,
        duration: float,
        rms: float,
        band: tuple[float, float],
        *,
        closed_loop: bool = False,
        seed: int | None = None,
    ) -> Columns:
        """Band-limited random drive excitation (paper Section 2, Fig. 3).

        Open loop (default): the drive input is the noise.  Closed loop: the noise is added to the
        controller output (the reference is 0).  Returns ``t, input`` (drive command),
        ``output`` (measured position) and ``excitation``.
        """
        if closed_loop and self.controller is None:
            raise InvalidInputError("a closed-loop noise test needs a position controller: the rig's `controller` is None")
        rng = np.random.default_rng(seed)
        n = int(round(positive("duration", duration) / self.dt))
        e = band_limited_noise(n, self.dt, positive("rms", rms), band, rng)
        noise = self.position_noise * rng.standard_normal(n) if self.position_noise > 0 else None
        if closed_loop:
            r = simulate_closed_loop(self.plant, self.friction, self.controller, np.zeros(n), self.dt, input_disturbance=e,
                                     measurement_noise=noise, quantization=self.encoder, drive_limit=self.drive_limit)
        else:
            r = simulate_closed_loop(self.plant, self.friction, None, None, self.dt, feedforward=e,
                                     measurement_noise=noise, quantization=self.encoder, drive_limit=self.drive_limit)
        return {"t": r.t, "input": r.command, "output": r.measured, "excitation": e, "position_true": r.position}


__all__ = ["VirtualRig", "band_limited_noise", "quantize"]
