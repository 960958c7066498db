"""The servo axis: plant with input delay (paper eq. 1), controllers, closed-loop simulation."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterator, Optional, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._validate import as_array, finite, non_negative, positive, same_length
from .errors import InvalidInputError
from .models import FrictionModel, native_friction

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure


@dataclass(frozen=True)
class Plant:
    """``Y(s)/U(s) = a / (s^2 + b s + c) * exp(-s delay)`` (paper eq. 1), SI units.

    Parameters
    ----------
    a : float
        Gain (m per input unit per s^2), > 0.
    b : float
        Damping term (1/s), >= 0.
    c : float
        Stiffness term (1/s^2), >= 0.
    delay : float
        Input delay (s); need not be a multiple of the simulation step.
    force_gain : float
        Force per unit of drive input (N/unit).  Friction and load forces (N) enter the plant as
        ``F / force_gain`` input units, undelayed.  For the paper, the motor constant that turns
        volts into newtons; for EMPS ``gtau``.
    """

    a: float
    b: float
    c: float
    delay: float = 0.0
    force_gain: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "a", positive("a", self.a))
        object.__setattr__(self, "b", non_negative("b", self.b))
        object.__setattr__(self, "c", non_negative("c", self.c))
        object.__setattr__(self, "delay", non_negative("delay", self.delay))
        object.__setattr__(self, "force_gain", positive("force_gain", self.force_gain))

    @classmethod
    def from_mass(cls, mass: float, damping: float = 0.0, stiffness: float = 0.0, delay: float = 0.0, force_gain: float = 1.0) -> "Plant":
        """Rigid body ``m y'' + d y' + k y = force_gain u(t - delay)``."""
        mass = positive("mass", mass)
        damping = non_negative("damping", damping)
        stiffness = non_negative("stiffness", stiffness)
        force_gain = positive("force_gain", force_gain)
        return cls(force_gain / mass, damping / mass, stiffness / mass, delay, force_gain)

    @property
    def params(self) -> tuple[float, float, float, float, float]:
        return (self.a, self.b, self.c, self.delay, self.force_gain)

    @property
    def mass(self) -> float:
        """Equivalent moving mass ``force_gain / a`` (kg)."""
        return self.force_gain / self.a

    def frequency_response(self, f: ArrayLike) -> NDArray[np.complex128]:
        """Complex response at frequencies ``f`` (Hz), delay included."""
        s = 2j * np.pi * as_array("f", f)
        return self.a / (s**2 + self.b * s + self.c) * np.exp(-s * self.delay)

    def simulate(self, u: ArrayLike, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Open-loop response to ``u[k]`` held over ``[k dt, (k+1) dt)``, from rest.

        Returns ``t, y`` with ``y[k]`` the position at ``t[k] = k dt`` (exact ZOH).
        """
        dt = positive("dt", dt)
        u_arr = as_array("u", u)
        y, _ = _gmsfric.simulate_open_loop(self.params, dt, u_arr)
        return np.arange(u_arr.size) * dt, y

    def to_control(self) -> Any:
        """A python-control ``TransferFunction`` with the delay as the attribute ``delay``
        (python-control has no pure delay; use ``control.pade`` for a rational approximation)."""
        try:
            import control  # type: ignore[import-not-found]
        except ImportError as exc:  # pragma: no cover - optional extra
            raise ImportError("python-control is not installed: pip install 'gmsfric[control]'") from exc
        tf = control.tf([self.a], [1.0, self.b, self.c])
        tf.delay = self.delay
        return tf


@dataclass(frozen=True)
class PID:
    """Discrete parallel PID on the error ``r - y``.

    Parameters
    ----------
    kp, ki, kd : float
        Gains (input units per m, per m s, times s/m).
    tf : float
        Derivative filter time constant (s); 0 = unfiltered.
    u_min, u_max : float
        Output limits; the integrator stops while saturated (anti-windup).
    """

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    tf: float = 0.0
    u_min: float = -np.inf
    u_max: float = np.inf

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd"):
            object.__setattr__(self, name, finite(name, getattr(self, name)))
        object.__setattr__(self, "tf", non_negative("tf", self.tf))
        if not (float(self.u_min) < float(self.u_max)):
            raise InvalidInputError(f"`u_min` must be < `u_max`, got {self.u_min} and {self.u_max}")

    def _native(self, dt: float) -> _gmsfric.ControllerSpec:
        return _gmsfric.ControllerSpec.pid(self.kp, self.ki, self.kd, self.tf, float(self.u_min), float(self.u_max), dt)


@dataclass(frozen=True)
class Cascade:
    """EMPS-style position/velocity cascade ``u = kp kv (r - q) - kv qdot``.

    ``qdot`` is the 2-tap FIR velocity ``(qf(k) - qf(k-1)) / dt`` with ``qf(k) = (q(k) + q(k-1))/2``.
    """

    kp: float
    kv: float
    u_min: float = -np.inf
    u_max: float = np.inf

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", finite("kp", self.kp))
        object.__setattr__(self, "kv", finite("kv", self.kv))
        if not (float(self.u_min) < float(self.u_max)):
            raise InvalidInputError(f"`u_min` must be < `u_max`, got {self.u_min} and {self.u_max}")

    def _native(self, dt: float) -> _gmsfric.ControllerSpec:
        return _gmsfric.ControllerSpec.cascade(self.kp, self.kv, float(self.u_min), float(self.u_max), dt)


@dataclass(frozen=True)
class PIDDOB:
    """:class:`PID` plus a disturbance observer (DOB) on the drive input.

    The observer estimates the input-equivalent disturbance (e.g. friction / force_gain) as
    ``d_hat = Q(s) [exp(-s delay) u - P_n(s)^-1 y]`` with the nominal plant
    ``P_n = a / (s^2 + b s + c)`` and input delay of ``nominal``, and the low-pass
    ``Q(s) = 1 / (tau s + 1)^2``, ``tau = 1 / (2 pi dob_cutoff_hz)``; the controller outputs
    ``clamp(u_pid + d_hat)``.  The observer uses the controller's own output: a ``feedforward``
    passed to :func:`simulate_closed_loop` is seen (and cancelled) as a disturbance.

    Parameters
    ----------
    pid : PID
        Gains and output limits.
    nominal : Plant
        Nominal plant of the observer (a, b, c, delay; force_gain unused).
    dob_cutoff_hz : float
        Q-filter cutoff (Hz), > 0 and below the Nyquist frequency of the step.
    """

    pid: PID
    nominal: Plant
    dob_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        if not isinstance(self.pid, PID):
            raise InvalidInputError(f"`pid` must be a PID, got {type(self.pid).__name__}")
        if not isinstance(self.nominal, Plant):
            raise InvalidInputError(f"`nominal` must be a Plant, got {type(self.nominal).__name__}")
        object.__setattr__(self, "dob_cutoff_hz", positive("dob_cutoff_hz", self.dob_cutoff_hz))

    def _native(self, dt: float) -> _gmsfric.ControllerSpec:
        p, n = self.pid, self.nominal
        return _gmsfric.ControllerSpec.pid_dob(p.kp, p.ki, p.kd, p.tf, float(p.u_min), float(p.u_max), dt, n.a, n.b, n.c, n.delay, self.dob_cutoff_hz)


Controller = Union[PID, Cascade, PIDDOB]


@dataclass(frozen=True)
class ClosedLoopResult:
    """Sampled closed-loop run; unpacks as ``t, position = result``.

    Attributes
    ----------
    t : ndarray
        Time (s), ``k dt``.
    reference, position, velocity, measured : ndarray
        Reference, true position (m), true velocity (m/s), position the controller saw.
    command : ndarray
        Drive input over each step, after the drive limit (input units).
    friction : ndarray
        Friction force over each step (N).
    """

    t: NDArray[np.float64]
    reference: NDArray[np.float64]
    position: NDArray[np.float64]
    velocity: NDArray[np.float64]
    measured: NDArray[np.float64]
    command: NDArray[np.float64]
    friction: NDArray[np.float64]

    @property
    def error(self) -> NDArray[np.float64]:
        """Tracking error ``reference - position`` (m)."""
        return self.reference - self.position

    def __iter__(self) -> Iterator[NDArray[np.float64]]:
        return iter((self.t, self.position))

    def plot(self, fig: "Optional[Figure]" = None, *, label: str | None = None) -> "Figure":
        """Position, tracking error, command and friction against time."""
        from .plotting import plot_closed_loop

        return plot_closed_loop(self, fig=fig, label=label)


def _drive_limits(drive_limit: float | tuple[float, float] | None) -> tuple[float, float]:
    if drive_limit is None:
        return (-np.inf, np.inf)
    if np.isscalar(drive_limit):
        lim = positive("drive_limit", drive_limit)  # type: ignore[arg-type]
        return (-lim, lim)
    lo, hi = drive_limit  # type: ignore[misc]
    lo, hi = float(lo), float(hi)
    if not lo < hi:
        raise InvalidInputError(f"`drive_limit` must be (low, high) with low < high, got {drive_limit}")
    return (lo, hi)


def simulate_closed_loop(
    plant: Plant,
    friction: FrictionModel | None,
    controller: Controller,
    reference: ArrayLike,
    dt: float,
    *,
    feedforward: ArrayLike | None = None,
    input_disturbance: ArrayLike | None = None,
    load_force: ArrayLike | None = None,
    measurement_noise: ArrayLike | None = None,
    quantization: float = 0.0,
    drive_limit: float | tuple[float, float] | None = None,
    initial_position: float | None = None,
    initial_velocity: float = 0.0,
) -> ClosedLoopResult:
    """Simulate the axis of the paper's Fig. 9 in closed loop.

    reference -> controller (+ ``feedforward`` + ``input_disturbance``) -> drive limit ->
    input delay -> plant, with the friction force (and ``load_force``) acting on the mechanics.
    The controller reads the position plus ``measurement_noise``, quantised to ``quantization``.

    Parameters
    ----------
    plant : Plant
    friction : friction model or None
        ``None`` simulates the frictionless axis.
    controller : PID, Cascade or PIDDOB
    reference : array_like
        Reference position (m) per sample.
    dt : float
        Step (s), > 0; the controller runs at this rate.
    feedforward, input_disturbance : array_like, optional
        Added to the controller output (input units), before the drive limit.
    load_force : array_like, optional
        External force on the mechanics (N), per sample.
    measurement_noise : array_like, optional
        Added to the measured position (m).
    quantization : float
        Encoder resolution (m); 0 = none.
    drive_limit : float or (float, float), optional
        Symmetric or (low, high) drive input limits.
    initial_position, initial_velocity : float
        Initial state; the position defaults to ``reference[0]``.

    Returns
    -------
    ClosedLoopResult
    """
    if not isinstance(plant, Plant):
        raise InvalidInputError(f"`plant` must be a Plant, got {type(plant).__name__}")
    if not isinstance(controller, (PID, Cascade, PIDDOB)):
        raise InvalidInputError(f"`controller` must be a PID, Cascade or PIDDOB, got {type(controller).__name__}")
    dt = positive("dt", dt)
    ref = as_array("reference", reference)
    n = ref.size

    def optional(name: str, values: ArrayLike | None) -> NDArray[np.float64] | None:
        if values is None:
            return None
        arr = as_array(name, values)
        if arr.size == 1 and n > 1:
            arr = np.full(n, arr[0])
        same_length(name, arr, "reference", n)
        return arr

    lo, hi = _drive_limits(drive_limit)
    out = _gmsfric.simulate_closed_loop(
        plant.params,
        native_friction(friction),
        controller._native(dt),
        ref,
        dt,
        optional("feedforward", feedforward),
        optional("input_disturbance", input_disturbance),
        optional("load_force", load_force),
        optional("measurement_noise", measurement_noise),
        non_negative("quantization", quantization),
        lo,
        hi,
        None if initial_position is None else finite("initial_position", initial_position),
        finite("initial_velocity", initial_velocity),
    )
    if out["measured"] is None:  # no noise, no quantisation: the controller saw the true position
        measured = out["position"].view()
        measured.flags.writeable = False
        out["measured"] = measured
    t = np.arange(n, dtype=np.float64)
    t *= dt  # in place: one allocation for the time axis
    return ClosedLoopResult(t=t, reference=ref, **out)
