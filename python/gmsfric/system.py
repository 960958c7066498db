"""The servo axis: plant with input delay (paper eq. 1), controllers, closed- and open-loop runs.

Every run goes through one path: :func:`simulate_closed_loop` (one run) and the functions of
:mod:`gmsfric.batch` (many) describe the run's inputs with the same keywords (:class:`RunOptions`),
turned into the core's one input description by :func:`run_inputs`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any, ClassVar, Iterable, Iterator, Mapping, Optional, Sequence, TypedDict, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._validate import as_array, count, finite, float_array, number, show, step
from .errors import InvalidInputError, SimulationError
from .models import FrictionModel, NativeBacked, native_friction

if TYPE_CHECKING:  # pragma: no cover
    from matplotlib.figure import Figure
    from typing_extensions import Unpack

    from .axis import AxisModel

#: Outputs a run can record (``record=``); ``error`` is ``reference - position``.
OUTPUTS = ("position", "velocity", "measured", "command", "friction", "error")
#: What a run records unless told otherwise.
DEFAULT_RECORD = ("position", "velocity", "measured", "command", "friction")


def _control_module() -> Any:
    try:
        import control  # type: ignore[import-not-found, import-untyped, unused-ignore]
    except ImportError as exc:  # pragma: no cover - optional extra
        raise ImportError("python-control is not installed: pip install 'gmsfric[control]'") from exc
    return control


def _finite_transfer_function(tf: Any, what: str) -> Any:
    """``tf`` when every coefficient is finite; else ``InvalidInputError`` naming ``what``
    (parameters each finite whose products overflow a double)."""
    coefficients = [np.asarray(c, dtype=float) for part in (tf.num, tf.den) for row in part for c in row]
    if not all(np.isfinite(c).all() for c in coefficients):
        raise InvalidInputError(f"{what} overflows a double")
    return tf


@dataclass(frozen=True)
class Plant(NativeBacked):
    """``Y(s)/U(s) = a / (s^2 + b s + c) * exp(-s delay)`` (paper eq. 1), SI units.

    Parameters
    ----------
    a : float
        Gain (m per input unit per s^2; rad per input unit per s^2 for a rotary axis), > 0.
    b : float
        Damping term (1/s), >= 0.
    c : float
        Stiffness term (1/s^2), >= 0.
    delay : float
        Input delay (s); need not be a multiple of the simulation step.
    force_gain : float
        Force per unit of drive input (N/unit; N m/unit for a rotary axis).  Friction and load
        forces enter the plant as ``F / force_gain`` input units, undelayed.  For the paper, the
        motor constant that turns volts into newtons; for EMPS ``gtau``.
    rotary : bool, optional (keyword)
        The plant of a rotary axis (rad, N m per drive unit): saved in the model file's
        ``"axis"`` and read back by ``load_model``.
    drive : {"V", "A", "N", "N m"}, optional (keyword)
        SI unit of the drive input (a voltage or a current command, or the force itself: ``"N"``,
        ``"N m"`` on a rotary axis, with ``force_gain`` 1), for the model file's units.
    """

    _native: ClassVar[_gmsfric.PlantSpec]

    a: float
    b: float
    c: float
    delay: float = 0.0
    force_gain: float = 1.0
    rotary: bool = field(default=False, kw_only=True)
    drive: str = field(default="V", kw_only=True)

    def __post_init__(self) -> None:
        if not isinstance(self.rotary, (bool, np.bool_)):
            raise InvalidInputError(f"`rotary` must be True or False, got {type(self.rotary).__name__}")
        if not isinstance(self.drive, str) or self.drive not in ("V", "A", "N", "N m"):
            raise InvalidInputError(f"`drive` must be \"V\", \"A\", \"N\" or \"N m\", got {show(self.drive)}")
        for name in ("a", "b", "c", "delay", "force_gain"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        object.__setattr__(self, "_native", _gmsfric.PlantSpec(*self.params))

    @classmethod
    def from_mass(cls, mass: float, damping: float = 0.0, stiffness: float = 0.0, delay: float = 0.0, force_gain: float = 1.0, *,
                  rotary: bool = False) -> "Plant":
        """Rigid body ``m y'' + d y' + k y = force_gain u(t - delay)`` (kg, N s/m, N/m; for a
        rotary axis kg m^2, N m s/rad, N m/rad)."""
        mass = finite("mass", mass)
        if not mass > 0:
            raise InvalidInputError(f"`mass` must be > 0, got {mass}")
        force_gain = finite("force_gain", force_gain)
        if not force_gain > 0:
            raise InvalidInputError(f"`force_gain` must be > 0, got {force_gain}")
        return cls(force_gain / mass, finite("damping", damping) / mass, finite("stiffness", stiffness) / mass, delay, force_gain, rotary=rotary)

    @property
    def params(self) -> tuple[float, float, float, float, float]:
        return (self.a, self.b, self.c, self.delay, self.force_gain)

    @property
    def mass(self) -> float:
        """Equivalent moving mass ``force_gain / a`` (kg; kg m^2 for a rotary axis)."""
        mass = self.force_gain / self.a
        if not np.isfinite(mass):
            raise InvalidInputError(f"the mass force_gain / a = {self.force_gain:g} / {self.a:g} overflows a double")
        return mass

    def frequency_response(self, f: ArrayLike, dt: float | None = None) -> NDArray[np.complex128]:
        """Complex response at frequencies ``f`` (Hz), delay included.

        With ``dt``, the response of the plant sampled at ``dt`` through a zero-order hold
        (exact, fractional delay included) at ``z = exp(2j pi f dt)``: what a discrete
        controller running at ``dt`` sees.
        """
        f_arr = as_array("f", f)
        if dt is None:
            with np.errstate(all="ignore"):
                s = 2j * np.pi * f_arr
                h = self.a / (s**2 + self.b * s + self.c) * np.exp(-s * self.delay)
        else:
            num, den = self._discrete_polynomials(dt)
            z = np.exp(2j * np.pi * f_arr * dt)
            with np.errstate(all="ignore"):
                h = np.polyval(num, z) / np.polyval(den, z)
        return _finite_response(h, f_arr)

    def _discrete_polynomials(self, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Numerator and denominator (in ``z``, highest power first) of the ZOH-sampled plant.

        ``x+ = Phi x + g_new u[k-m] + g_old u[k-m-1]``, ``y = x_0``: with
        ``C adj(zI - Phi) g = g_0 z + (phi_01 g_1 - phi_11 g_0)``, multiplied through by
        ``z^(m+1)``.
        """
        phi, g_old, g_new, _, m = self._native.discretize(finite("dt", dt))
        p00, p01, p10, p11 = phi
        if m > 100_000:
            raise InvalidInputError(f"a delay of {m} steps at dt = {dt} s is too long for a transfer function")
        num = np.array([g_new[0], p01 * g_new[1] - p11 * g_new[0] + g_old[0], p01 * g_old[1] - p11 * g_old[0]])
        den = np.concatenate(([1.0, -(p00 + p11), p00 * p11 - p01 * p10], np.zeros(m + 1)))
        return num, den

    def simulate(self, u: ArrayLike, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Open-loop response to ``u[k]`` held over ``[k dt, (k+1) dt)``, from rest.

        Returns ``t, y`` with ``y[k]`` the position at ``t[k] = k dt`` (exact ZOH).
        """
        res = simulate_closed_loop(self, None, None, None, dt, feedforward=u, record=("position",))
        assert res.position is not None
        return res.t, res.position

    def to_control(self, pade_order: int | None = None, dt: float | None = None) -> Any:
        """The plant as a python-control ``TransferFunction``, delay included.

        Parameters
        ----------
        pade_order : int, optional
            Continuous time, the delay replaced by a Pade approximation of this order. Refused
            for delays below a nanosecond (the approximation's poles would lie beyond 1e9 rad/s).
        dt : float, optional
            Discrete time: the exact zero-order-hold equivalent at step ``dt`` with the
            (fractional) delay as extra poles at ``z = 0`` and a split numerator, computed by the
            core exactly as the simulations use it.

        Without either, a plant with a delay is refused: python-control has no pure delay, and a
        transfer function without it would give wrong margins.
        """
        control = _control_module()
        if dt is not None and pade_order is not None:
            raise InvalidInputError("give either `pade_order` (continuous time) or `dt` (discrete time), not both")
        if dt is not None:
            num, den = self._discrete_polynomials(dt)
            return control.tf(num, den, step("dt", dt))
        tf = control.tf([self.a], [1.0, self.b, self.c])
        if self.delay == 0:
            return tf
        if pade_order is None:
            raise InvalidInputError(
                f"the plant has a {self.delay:g} s delay, which a rational transfer function cannot hold: "
                "give pade_order= (continuous, approximated) or dt= (discrete, exact)"
            )
        order = count("pade_order", pade_order, minimum=1, maximum=10)
        if self.delay < 1e-9:
            raise InvalidInputError(f"a Pade approximation of a {self.delay:g} s delay puts poles beyond 1e9 rad/s; drop the delay or use dt=")
        with np.errstate(over="ignore", invalid="ignore"):
            num, den = control.pade(self.delay, order)
            delayed = tf * control.tf(num, den)
        return _finite_transfer_function(delayed, f"the plant's Pade approximation (delay = {self.delay:g} s, order {order})")

    @classmethod
    def from_control(cls, tf: Any, delay: float = 0.0, force_gain: float = 1.0) -> "Plant":
        """A plant from a continuous python-control ``a / (s^2 + b s + c)`` (any scaling of the
        denominator); the delay and force gain are given separately."""
        if getattr(tf, "dt", 0) not in (0, None):
            raise InvalidInputError("`tf` must be a continuous-time transfer function (dt = 0)")
        try:
            num = np.trim_zeros(np.atleast_1d(np.squeeze(tf.num[0][0])).astype(float), "f")
            den = np.trim_zeros(np.atleast_1d(np.squeeze(tf.den[0][0])).astype(float), "f")
        except (AttributeError, IndexError, TypeError) as exc:
            raise InvalidInputError(f"`tf` must be a SISO python-control TransferFunction: {exc}") from None
        if num.size != 1 or den.size != 3 or den[0] == 0:
            raise InvalidInputError(f"`tf` must be a / (s^2 + b s + c), got numerator {num.tolist()} and denominator {den.tolist()}")
        return cls(num[0] / den[0], den[1] / den[0], den[2] / den[0], delay, force_gain)


def _finite_response(h: NDArray[np.complex128], f: NDArray[np.float64]) -> NDArray[np.complex128]:
    """``h``, or ``InvalidInputError`` naming the first frequency whose response is not finite."""
    bad = ~np.isfinite(h)
    if bad.any():
        raise InvalidInputError(f"`f` = {f[bad][0]:g} Hz gives a non-finite response (a pole there, or a frequency out of range)")
    return h


def _limits(u_min: Any, u_max: Any) -> tuple[float, float]:
    return number("u_min", u_min), number("u_max", u_max)


@dataclass(frozen=True)
class PID(NativeBacked):
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

    _native: ClassVar[_gmsfric.ControllerSpec]

    kp: float
    ki: float = 0.0
    kd: float = 0.0
    tf: float = 0.0
    u_min: float = -np.inf
    u_max: float = np.inf

    def __post_init__(self) -> None:
        for name in ("kp", "ki", "kd", "tf"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        lo, hi = _limits(self.u_min, self.u_max)
        object.__setattr__(self, "u_min", lo)
        object.__setattr__(self, "u_max", hi)
        object.__setattr__(self, "_native", _gmsfric.ControllerSpec.pid(self.kp, self.ki, self.kd, self.tf, lo, hi))

    def frequency_response(self, f: ArrayLike, dt: float) -> NDArray[np.complex128]:
        """Response of the discrete PID running at ``dt`` (limits ignored) at frequencies ``f``.

        A frequency where the response is infinite (0 Hz with an integrator) or overflows
        raises ``InvalidInputError`` naming it.
        """
        num, den = self._discrete_polynomials(dt)
        f_arr = as_array("f", f)
        with np.errstate(all="ignore"):
            h = np.polyval(num, np.exp(2j * np.pi * f_arr * dt)) / np.polyval(den, np.exp(2j * np.pi * f_arr * dt))
        return _finite_response(h, f_arr)

    def _discrete_polynomials(self, dt: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``C(z) = kp + ki dt z / (z - 1) + kd (z - 1) / ((tf + dt) z - tf)``, the exact transfer
        function of the core's update (integral updated before use, backward-Euler filter)."""
        dt = step("dt", dt)
        p = np.polynomial.polynomial
        d1 = np.array([-1.0, 1.0])  # z - 1, low powers first
        d2 = np.array([-self.tf, self.tf + dt])  # (tf + dt) z - tf
        with np.errstate(all="ignore"):
            num = p.polyadd(p.polyadd(self.kp * p.polymul(d1, d2), self.ki * dt * p.polymul([0.0, 1.0], d2)), self.kd * p.polymul(d1, d1))
            den = p.polymul(d1, d2)
        if not (np.isfinite(num).all() and np.isfinite(den).all()):
            raise InvalidInputError(f"the PID's discrete transfer function overflows at a step of {dt:g} s (gains kp = {self.kp:g}, "
                                    f"ki = {self.ki:g}, kd = {self.kd:g}, tf = {self.tf:g})")
        return num[::-1], den[::-1]

    def to_control(self, dt: float | None = None) -> Any:
        """The PID as a python-control ``TransferFunction``: continuous
        ``kp + ki/s + kd s/(tf s + 1)``, or with ``dt`` the exact discrete controller the core runs."""
        control = _control_module()
        if dt is not None:
            num, den = self._discrete_polynomials(dt)
            return control.tf(num, den, step("dt", dt))
        s = control.tf("s")
        with np.errstate(over="ignore", invalid="ignore"):
            tf = self.kp + self.ki / s + self.kd * s / (self.tf * s + 1)
        return _finite_transfer_function(tf, f"the PID's transfer function (kp = {self.kp:g}, ki = {self.ki:g}, kd = {self.kd:g}, tf = {self.tf:g})")


@dataclass(frozen=True)
class Cascade(NativeBacked):
    """EMPS-style position/velocity cascade ``u = kp kv (r - q) - kv qdot``.

    ``qdot`` is the 2-tap FIR velocity ``(qf(k) - qf(k-1)) / dt`` with ``qf(k) = (q(k) + q(k-1))/2``.
    """

    _native: ClassVar[_gmsfric.ControllerSpec]

    kp: float
    kv: float
    u_min: float = -np.inf
    u_max: float = np.inf

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", number("kp", self.kp))
        object.__setattr__(self, "kv", number("kv", self.kv))
        lo, hi = _limits(self.u_min, self.u_max)
        object.__setattr__(self, "u_min", lo)
        object.__setattr__(self, "u_max", hi)
        object.__setattr__(self, "_native", _gmsfric.ControllerSpec.cascade(self.kp, self.kv, lo, hi))


@dataclass(frozen=True)
class PIDDOB(NativeBacked):
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

    _native: ClassVar[_gmsfric.ControllerSpec]

    pid: PID
    nominal: Plant
    dob_cutoff_hz: float = 20.0

    def __post_init__(self) -> None:
        if not isinstance(self.pid, PID):
            raise InvalidInputError(f"`pid` must be a PID, got {type(self.pid).__name__}")
        if not isinstance(self.nominal, Plant):
            raise InvalidInputError(f"`nominal` must be a Plant, got {type(self.nominal).__name__}")
        object.__setattr__(self, "dob_cutoff_hz", number("dob_cutoff_hz", self.dob_cutoff_hz))
        p, n = self.pid, self.nominal
        spec = _gmsfric.ControllerSpec.pid_dob(p.kp, p.ki, p.kd, p.tf, p.u_min, p.u_max, n.a, n.b, n.c, n.delay, self.dob_cutoff_hz)
        object.__setattr__(self, "_native", spec)


Controller = Union[PID, Cascade, PIDDOB]


def native_controller(controller: Controller | None, name: str = "controller") -> _gmsfric.ControllerSpec | None:
    """The compiled spec of a controller (``None``, open loop, passes through)."""
    if controller is None:
        return None
    if not isinstance(controller, (PID, Cascade, PIDDOB)):
        raise InvalidInputError(f"`{name}` must be a PID, Cascade, PIDDOB or None (open loop), got {type(controller).__name__}")
    return controller._native


class RunOptions(TypedDict, total=False):
    """The inputs of a run besides the reference: every simulation function takes these keywords.

    Attributes
    ----------
    feedforward : array_like
        Added to the controller output (input units), before the drive limit; without a
        controller, the drive command itself.
    input_disturbance : array_like
        Also added to the controller output (input units), e.g. EMPS's pulses.
    load_force : array_like
        External force on the mechanics (N), per sample; opposes motion like friction.
    measurement_noise : array_like
        Added to the measured position (m).
    quantization : float
        Encoder resolution (m); 0 = none.
    drive_limit : float or (float, float)
        Symmetric or (low, high) drive input limits.
    initial_position, initial_velocity : float
        Initial state; the position defaults to ``reference[0]`` (0 in open loop).
    record : sequence of str
        Outputs to record among :data:`OUTPUTS` (default :data:`DEFAULT_RECORD`): a run that needs
        one array does not write five.
    every : int
        Record every ``every``-th sample (decimation; 1 = all).

    Arrays are 1-D; the batch functions also take 2-D arrays (one row per run).
    """

    feedforward: ArrayLike | None
    input_disturbance: ArrayLike | None
    load_force: ArrayLike | None
    measurement_noise: ArrayLike | None
    quantization: float
    drive_limit: float | tuple[float, float] | None
    initial_position: float | None
    initial_velocity: float
    record: Sequence[str] | str
    every: int


_OPTION_ARRAYS = ("feedforward", "input_disturbance", "load_force", "measurement_noise")


def _rows(name: str, values: ArrayLike, n_runs: int, n: int | None, *, allow_2d: bool) -> NDArray[np.float64]:
    """A C-contiguous float64 ``(1 or n_runs, n)`` array; a 1-D input becomes one shared row (a
    view: no copy when it already is contiguous float64)."""
    arr = float_array(name, values)
    if arr.ndim == 1:
        if n is not None and arr.size == 1 and n > 1:
            arr = np.full(n, arr[0])
        arr = arr.reshape(1, -1)
    elif arr.ndim != 2 or not allow_2d:
        want = "1-D (shared by every run) or 2-D (one row per run)" if allow_2d else "one-dimensional"
        raise InvalidInputError(f"`{name}` must be {want}, got shape {arr.shape}")
    if arr.shape[0] not in (1, n_runs):
        raise InvalidInputError(f"`{name}` has {arr.shape[0]} rows but there are {n_runs} runs: give 1 row or one per run")
    if arr.shape[1] == 0:
        raise InvalidInputError(f"`{name}` is empty")
    if n is not None and arr.shape[1] != n:
        raise InvalidInputError(f"`{name}` has length {arr.shape[1]} but the run has {n} samples: they must match")
    # A finite sum means every value is finite (inf and nan propagate); only a sum that
    # overflowed or met a non-finite value needs the element-wise test.
    with np.errstate(over="ignore", invalid="ignore"):
        total = arr.sum()
    if not np.isfinite(total) and not np.isfinite(arr).all():
        r, c = np.argwhere(~np.isfinite(arr))[0]
        where = f"index {c}" if arr.shape[0] == 1 else f"row {r}, index {c}"
        raise InvalidInputError(f"`{name}` has a non-finite value ({arr[r, c]}) at {where}")
    return arr


def _drive_limits(drive_limit: Any) -> tuple[float, float]:
    if drive_limit is None:
        return (-np.inf, np.inf)
    try:
        scalar = np.ndim(drive_limit) == 0
    except (ValueError, TypeError):  # a ragged sequence: taken as a pair, refused there
        scalar = False
    if scalar:
        lim = number("drive_limit", drive_limit)
        return (-lim, lim)
    try:
        lo, hi = (number("drive_limit", v) for v in drive_limit)
    except ValueError:
        raise InvalidInputError(f"`drive_limit` must be a number or a (low, high) pair, got {drive_limit!r}") from None
    return (lo, hi)


def run_inputs(reference: ArrayLike | None, n_runs: int, options: Mapping[str, Any], *, allow_2d: bool) -> tuple[dict[str, Any], tuple[str, ...], int]:
    """The core's description of the runs from :class:`RunOptions` keywords: ``(inputs, record,
    every)``. Unknown keywords are refused, naming them."""
    unknown = set(options) - set(RunOptions.__annotations__)
    if unknown:
        raise InvalidInputError(f"unknown option(s) {sorted(unknown)}; the options are {sorted(RunOptions.__annotations__)}")
    ref = None if reference is None else _rows("reference", reference, n_runs, None, allow_2d=allow_2d)
    n = None if ref is None else ref.shape[1]
    arrays: dict[str, Any] = {}
    for name in _OPTION_ARRAYS:
        value = options.get(name)
        arrays[name] = None if value is None else _rows(name, value, n_runs, n, allow_2d=allow_2d)
        if n is None and arrays[name] is not None:
            n = arrays[name].shape[1]
    if ref is None and arrays["feedforward"] is None:
        raise InvalidInputError("give a `reference` (closed loop) or a `feedforward` command (open loop)")
    lo, hi = _drive_limits(options.get("drive_limit"))
    x0 = options.get("initial_position")
    record = options.get("record", DEFAULT_RECORD)
    if isinstance(record, str):
        record = (record,)
    if isinstance(record, (bytes, dict)) or not isinstance(record, Iterable):
        raise InvalidInputError(f"`record` must be output names among {OUTPUTS}, got {show(record)}")
    record = tuple(record)
    for r in record:
        if not isinstance(r, str) or r not in OUTPUTS:
            raise InvalidInputError(f"`record` has an unknown output {show(r)}; choose among {OUTPUTS}")
    inputs = {
        "reference": ref,
        **arrays,
        "quantization": number("quantization", options.get("quantization", 0.0)),
        "drive_min": lo,
        "drive_max": hi,
        "initial_position": None if x0 is None else number("initial_position", x0),
        "initial_velocity": number("initial_velocity", options.get("initial_velocity", 0.0)),
    }
    return inputs, record, count("every", options.get("every", 1))


@dataclass(frozen=True)
class ClosedLoopResult:
    """Sampled run; unpacks as ``t, position = result``.

    Outputs not recorded (``record=``) are ``None``.

    Attributes
    ----------
    dt : float
        Step of the run (s).
    reference : ndarray or None
        Reference at the recorded samples (``None`` in open loop).
    position, velocity, measured : ndarray or None
        True position (m), true velocity (m/s), position the controller saw.
    command : ndarray or None
        Drive input over each step, after the drive limit (input units).
    friction : ndarray or None
        Force of friction and effects over each step (N).
    every : int
        Decimation: the recorded samples are steps ``0, every, 2 every, ...``.
    t : ndarray
        Time (s) of the recorded samples, ``k dt`` (every ``every``-th); built on first use,
        so a run that only needs one output does not pay for a time axis.
    """

    dt: float
    reference: Optional[NDArray[np.float64]]
    position: Optional[NDArray[np.float64]] = None
    velocity: Optional[NDArray[np.float64]] = None
    measured: Optional[NDArray[np.float64]] = None
    command: Optional[NDArray[np.float64]] = None
    friction: Optional[NDArray[np.float64]] = None
    recorded_error: Optional[NDArray[np.float64]] = None
    every: int = 1

    @cached_property
    def t(self) -> NDArray[np.float64]:
        """Time (s) of the recorded samples."""
        arrays = (self.position, self.velocity, self.measured, self.command, self.friction, self.recorded_error, self.reference)
        n = next((a.shape[-1] for a in arrays if a is not None), 0)
        t = np.arange(0, n * self.every, self.every, dtype=np.float64)[:n]
        t *= self.dt  # in place: one allocation for the time axis
        return t

    @property
    def error(self) -> NDArray[np.float64]:
        """Tracking error ``reference - position`` (m)."""
        if self.recorded_error is not None:
            return self.recorded_error
        if self.position is None:
            raise InvalidInputError("the run recorded neither `error` nor `position`")
        return (0.0 if self.reference is None else self.reference) - self.position

    def __iter__(self) -> Iterator[Any]:
        return iter((self.t, self.position))

    def plot(self, fig: "Optional[Figure]" = None, *, label: str | None = None) -> "Figure":
        """Position, tracking error, command and friction against time."""
        from .plotting import plot_closed_loop

        return plot_closed_loop(self, fig=fig, label=label)


def _measured_view(out: dict[str, Any], record: tuple[str, ...], inputs: Mapping[str, Any]) -> dict[str, Any]:
    """The recorded outputs; without noise or quantisation the controller saw the true position,
    and a read-only view of it stands for ``measured`` (same values, no second array written)."""
    if "measured" in record and "measured" not in out:
        view = out["position"].view()
        view.flags.writeable = False
        out["measured"] = view
    return {k: v for k, v in out.items() if k in record}


def _record_for_core(record: tuple[str, ...], inputs: Mapping[str, Any]) -> list[str]:
    names = list(record)
    if "measured" in names and inputs["measurement_noise"] is None and inputs["quantization"] == 0:
        names.remove("measured")
        if "position" not in names:
            names.append("position")
    return names


def axis_of(plant: "Plant | AxisModel", friction: FrictionModel | None, names: tuple[str, str] = ("plant", "friction")) -> _gmsfric.AxisSpec:
    """The core's axis for a plant and a friction model, or for an :class:`~gmsfric.axis.AxisModel`
    (which carries its own friction and effects)."""
    from .axis import AxisModel

    if isinstance(plant, AxisModel):
        if friction is not None:
            raise InvalidInputError(f"an AxisModel carries its own friction: pass `{names[1]}` = None")
        return plant._native
    if not isinstance(plant, Plant):
        raise InvalidInputError(f"`{names[0]}` must be a Plant or an AxisModel, got {type(plant).__name__}")
    return _gmsfric.AxisSpec(plant._native, native_friction(friction, names[1]))


def simulate_closed_loop(
    plant: "Plant | AxisModel",
    friction: FrictionModel | None,
    controller: Controller | None,
    reference: ArrayLike | None,
    dt: float,
    **options: "Unpack[RunOptions]",
) -> ClosedLoopResult:
    """Simulate the axis of the paper's Fig. 9, in closed loop or (``controller=None``) open loop.

    reference -> controller (+ ``feedforward`` + ``input_disturbance``) -> drive limit ->
    input delay -> plant, with the friction force (and effects, and ``load_force``) acting on the
    mechanics. The controller reads the position plus ``measurement_noise``, quantised to
    ``quantization``.

    Parameters
    ----------
    plant : Plant or AxisModel
        The axis; an :class:`~gmsfric.axis.AxisModel` brings its friction model and effects.
    friction : friction model or None
        ``None`` simulates the frictionless axis (or the AxisModel's own friction).
    controller : PID, Cascade, PIDDOB or None
        ``None``: open loop, the drive command is ``feedforward``.
    reference : array_like or None
        Reference position (m) per sample; may be ``None`` in open loop.
    dt : float
        Step (s), > 0; the controller runs at this rate.
    **options
        The run's other inputs and what to record: see :class:`RunOptions`.

    Returns
    -------
    ClosedLoopResult
    """
    axis = axis_of(plant, friction)
    ctrl = native_controller(controller)
    dt = number("dt", dt)
    if ctrl is not None and reference is None:
        raise InvalidInputError("a closed-loop run needs a `reference` (or pass controller=None for open loop)")
    inputs, record, every = run_inputs(reference, 1, options, allow_2d=False)
    out = _gmsfric.simulate([axis], [ctrl], dt, inputs, _record_for_core(record, inputs), every, 1)
    rows = _measured_view({k: v[0] for k, v in out.items()}, record, inputs)
    ref = None if inputs["reference"] is None else inputs["reference"][0, ::every]
    return ClosedLoopResult(
        dt=dt,
        every=every,
        reference=ref,
        position=rows.get("position"),
        velocity=rows.get("velocity"),
        measured=rows.get("measured"),
        command=rows.get("command"),
        friction=rows.get("friction"),
        recorded_error=rows.get("error"),
    )


__all__ = [
    "Plant",
    "PID",
    "Cascade",
    "PIDDOB",
    "Controller",
    "RunOptions",
    "OUTPUTS",
    "DEFAULT_RECORD",
    "ClosedLoopResult",
    "simulate_closed_loop",
    "run_inputs",
    "native_controller",
    "axis_of",
    "SimulationError",
]
