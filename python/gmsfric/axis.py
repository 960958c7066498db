"""One model of an axis through the whole toolchain: plant, friction, effects, units,
covariance and provenance.

An :class:`AxisModel` is what identification produces, what the loop refines, what ``glitch``,
the batch functions and the output-error fit simulate, and what ``save_model``/``load_model``
carry between commands. Everything inside is SI (m, m/s, N, kg; rad, rad/s, N m, kg m^2 for a
rotary axis); :class:`AxisUnits` only says how to show it.

The effects (:class:`Effects`) are simulated *in feedback* by the core, on any trajectory:

================================  ==========================================================
``asymmetry``                     Coulomb level ``+-d_level``, viscous ``+-d_viscous`` per direction
``position_force``                ``g(q)`` (N), cogging, springs, gravity, cables
``position_friction``             ``g(q)`` added to the Coulomb level
``drift``                         levels changing over a run, ``h(t)`` linear or exponential
``heating``                       levels changing with the recent motion (speed low-passed, ``tau``)
``blocks``                        pre-sliding Maxwell-slip blocks ``(k_i, w_i)`` beside the friction
``compliance``                    a load ``mass`` on a spring-damper (``fn_hz``, ``zeta``)
``input_delay``                   the plant's ``delay``
================================  ==========================================================

Level-changing effects (asymmetry, position-dependent friction, drift, heating) need a static-map
friction.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Literal, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._validate import as_array, choice, count, number, show
from .errors import InvalidInputError
from .models import GMS, FrictionModel, LuGre, MaxwellSlip, NativeBacked, StaticFriction, native_friction
from .system import Controller, Plant

if TYPE_CHECKING:  # pragma: no cover
    from typing_extensions import Unpack

    from .system import ClosedLoopResult, RunOptions

SeriesKind = Literal["legendre", "fourier", "table"]
Beyond = Literal["hold", "linear"]


def _floats(name: str, values: Any) -> tuple[float, ...]:
    """A tuple of floats from a sequence (empty allowed: the core says what it needs)."""
    if values is None or isinstance(values, (str, bytes)):
        raise InvalidInputError(f"`{name}` must be a sequence of numbers, got {show(values)}")
    try:
        arr = np.atleast_1d(np.asarray(values, dtype=float))
    except (TypeError, ValueError, OverflowError) as exc:
        raise InvalidInputError(f"`{name}` must be numeric: {exc}") from None
    if arr.ndim != 1:
        raise InvalidInputError(f"`{name}` must be one-dimensional, got shape {arr.shape}")
    return tuple(float(v) for v in arr)


def legendre_columns(x: ArrayLike, degree: int, linear: bool) -> NDArray[np.float64]:
    """The Legendre polynomials ``P_0 .. P_degree`` over the travel, and what they do beyond it.

    Parameters
    ----------
    x : array_like
        Positions scaled to the travel (``-1`` and ``1`` at its ends; beyond them outside it).
    degree : int
        Highest degree.
    linear : bool
        Beyond the travel, let ``P_1`` go on (its slope is that of a series' best straight line
        over the travel) while the curved polynomials hold their edge values; otherwise every
        polynomial holds its edge value.

    Returns
    -------
    ndarray
        Shape ``(len(x), degree + 1)``; a series is ``legendre_columns(x, d, linear) @ coef``.
    """
    x = np.asarray(x, dtype=float)
    xc = np.clip(x, -1.0, 1.0)
    cols = np.polynomial.legendre.legvander(xc, degree)
    if linear and degree >= 1:
        cols[:, 1] += x - xc
    return cols


@dataclass(frozen=True)
class PositionSeries:
    """A function of position ``g(q)``: a series or a table.

    Use the constructors: :meth:`legendre` (smooth: springs, gravity, wear along the travel),
    :meth:`fourier` (periodic: cogging, screw pitch), :meth:`table` (measured, interpolated).
    ``beyond`` says what a Legendre series does beyond its travel: ``"hold"`` its edge value or
    ``"linear"`` go on with the slope of its degree-1 term.
    """

    kind: SeriesKind
    coef: tuple[float, ...] = ()
    lo: float = 0.0
    hi: float = 0.0
    periods: tuple[float, ...] = ()
    harmonics: int = 0
    q0: float = 0.0
    dq: float = 0.0
    values: tuple[float, ...] = ()
    beyond: Beyond = "hold"

    def __post_init__(self) -> None:
        choice("kind", self.kind, ("legendre", "fourier", "table"))
        choice("beyond", self.beyond, ("hold", "linear"))
        for name in ("coef", "periods", "values"):
            object.__setattr__(self, name, _floats(name, getattr(self, name)))
        for name in ("lo", "hi", "q0", "dq"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        object.__setattr__(self, "harmonics", count("harmonics", self.harmonics, minimum=0))
        # The core validates the combination (travel, lengths, finiteness).
        _gmsfric.AxisSpec(_gmsfric.PlantSpec(1.0, 0.0, 0.0, 0.0, 1.0), None, position_force=self.core_args())

    @classmethod
    def legendre(cls, lo: float, hi: float, coef: ArrayLike, beyond: Beyond = "hold") -> "PositionSeries":
        """``sum_d coef[d] P_d(x)``, ``x = 2 (q - lo)/(hi - lo) - 1`` over the travel ``[lo, hi]``.

        Beyond the travel the series is held at its edge value (``beyond="hold"``), or its
        degree-1 term goes on while the curved terms hold (``"linear"``: a spring or a weight
        goes on growing, a bump does not)."""
        return cls("legendre", coef=tuple(as_array("coef", coef)), lo=lo, hi=hi, beyond=beyond)

    @classmethod
    def fourier(cls, periods: ArrayLike, harmonics: int, coef: ArrayLike) -> "PositionSeries":
        """``sum_p sum_h a sin(2 pi h q / p) + b cos(...)``; ``coef`` as (a, b) pairs, period by
        period, harmonic by harmonic."""
        return cls("fourier", coef=tuple(as_array("coef", coef)), periods=tuple(as_array("periods", periods)), harmonics=harmonics)

    @classmethod
    def table(cls, q: ArrayLike, values: ArrayLike) -> "PositionSeries":
        """Linear interpolation of ``values`` at uniformly spaced positions ``q`` (constant beyond)."""
        q_arr, v_arr = as_array("q", q, min_len=2), as_array("values", values, min_len=2)
        if q_arr.size != v_arr.size:
            raise InvalidInputError(f"`values` has length {v_arr.size} but `q` has length {q_arr.size}")
        dq = np.diff(q_arr)
        if not (np.all(dq > 0) and np.allclose(dq, dq[0], rtol=1e-6)):
            raise InvalidInputError("`q` must be uniformly spaced and increasing")
        return cls("table", q0=float(q_arr[0]), dq=float(dq.mean()), values=tuple(v_arr))

    def core_args(self) -> dict[str, Any]:
        """The series as the core's constructor takes it."""
        if self.kind == "legendre":
            return {"kind": "legendre", "lo": self.lo, "hi": self.hi, "coef": list(self.coef), "linear_beyond": self.beyond == "linear"}
        if self.kind == "fourier":
            return {"kind": "fourier", "periods": list(self.periods), "harmonics": self.harmonics, "coef": list(self.coef)}
        return {"kind": "table", "q0": self.q0, "dq": self.dq, "values": list(self.values)}

    def __call__(self, q: ArrayLike) -> NDArray[np.float64]:
        """``g(q)`` on positions ``q`` (numpy; the core evaluates the same series in simulations)."""
        q = as_array("q", q)
        if self.kind == "legendre":
            x = 2.0 * (q - self.lo) / (self.hi - self.lo) - 1.0
            return legendre_columns(x, len(self.coef) - 1, self.beyond == "linear") @ np.asarray(self.coef)
        if self.kind == "fourier":
            out = np.zeros_like(q)
            c = iter(self.coef)
            for p in self.periods:
                for h in range(1, self.harmonics + 1):
                    w = 2 * np.pi * h / p
                    out += next(c) * np.sin(w * q) + next(c) * np.cos(w * q)
            return out
        grid = self.q0 + self.dq * np.arange(len(self.values))
        return np.interp(q, grid, np.asarray(self.values))


@dataclass(frozen=True)
class Drift:
    """Friction levels that change over a run: Coulomb ``+ d_level h(t)``, viscous
    ``+ d_viscous h(t)``, with ``h = t / scale - 1/2`` (``"linear"``, ``scale`` = the duration it
    was fitted on) or ``h = exp(-t / scale)`` (``"exponential"``, warm-up); ``t`` from the run's start."""

    shape: Literal["linear", "exponential"]
    scale: float
    d_level: float = 0.0
    d_viscous: float = 0.0

    def __post_init__(self) -> None:
        choice("shape", self.shape, ("linear", "exponential"))

    def core_args(self) -> tuple[str, float, float, float]:
        return (self.shape, number("scale", self.scale), number("d_level", self.d_level), number("d_viscous", self.d_viscous))


@dataclass(frozen=True)
class Heating:
    """Friction that changes with the recent motion (a lubricant warming up): the speed
    low-passed with time constant ``tau`` (s), ``m' = (|v| - m) / tau``, shifts the Coulomb level
    by ``d_level * m`` (N per m/s) and the viscous coefficient by ``d_viscous * m``. ``m`` starts
    at the run's initial speed."""

    tau: float
    d_level: float = 0.0
    d_viscous: float = 0.0

    def core_args(self) -> tuple[float, float, float]:
        return (number("tau", self.tau), number("d_level", self.d_level), number("d_viscous", self.d_viscous))


@dataclass(frozen=True)
class Compliance:
    """A load of ``mass`` (kg) on a spring-damper (``fn_hz``, damping ratio ``zeta``) behind the
    simulated mass; the plant is then the motor side only."""

    mass: float
    fn_hz: float
    zeta: float = 0.1


@dataclass(frozen=True)
class Effects:
    """What an axis has beyond its plant and friction model (all optional); see the module doc."""

    asymmetry: tuple[float, float] | None = None
    position_force: PositionSeries | None = None
    position_friction: PositionSeries | None = None
    drift: Drift | None = None
    heating: Heating | None = None
    blocks: MaxwellSlip | None = None
    compliance: Compliance | None = None

    def __post_init__(self) -> None:
        if self.asymmetry is not None:
            pair = self.asymmetry
            if isinstance(pair, (str, bytes, dict)) or np.ndim(pair) != 1 or len(pair) != 2:
                raise InvalidInputError(f"`asymmetry` must be a (d_level, d_viscous) pair, got {show(pair)}")
            object.__setattr__(self, "asymmetry", (number("asymmetry", pair[0]), number("asymmetry", pair[1])))
        for name, kind in (("position_force", PositionSeries), ("position_friction", PositionSeries), ("drift", Drift), ("heating", Heating), ("blocks", MaxwellSlip), ("compliance", Compliance)):
            value = getattr(self, name)
            if value is not None and not isinstance(value, kind):
                raise InvalidInputError(f"`{name}` must be a {kind.__name__}, got {type(value).__name__}")

    @property
    def names(self) -> list[str]:
        """The effects present."""
        return [f.name for f in dataclasses.fields(self) if getattr(self, f.name) is not None]

    def core_args(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.asymmetry is not None:
            out["asymmetry"] = self.asymmetry
        if self.position_force is not None:
            out["position_force"] = self.position_force.core_args()
        if self.position_friction is not None:
            out["position_friction"] = self.position_friction.core_args()
        if self.drift is not None:
            out["drift"] = self.drift.core_args()
        if self.heating is not None:
            out["heating"] = self.heating.core_args()
        if self.blocks is not None:
            out["blocks"] = (list(self.blocks.k), list(self.blocks.w))
        if self.compliance is not None:
            c = self.compliance
            out["compliance"] = (number("mass", c.mass), number("fn_hz", c.fn_hz), number("zeta", c.zeta))
        return out


@dataclass(frozen=True)
class AxisUnits:
    """How the axis is shown: ``kind`` ``"linear"`` (m, N, kg) or ``"rotary"`` (rad, N m, kg m^2),
    and the drive command's unit: ``"V"``, ``"A"``, or the force's (``"N"``, ``"N m"``) when the
    command is the force itself (then ``plant.force_gain`` is 1 N/N). Values inside are always SI."""

    kind: Literal["linear", "rotary"] = "linear"
    command: str = "V"

    def __post_init__(self) -> None:
        choice("kind", self.kind, ("linear", "rotary"))
        if not isinstance(self.command, str):
            raise InvalidInputError(f"`command` must be a unit string (V, A ...), got {show(self.command)}")

    @property
    def position(self) -> str:
        return "m" if self.kind == "linear" else "rad"

    @property
    def force(self) -> str:
        return "N" if self.kind == "linear" else "N m"


@dataclass(frozen=True)
class Covariance:
    """Parameter covariance in SI: ``names`` are parameter paths of :meth:`AxisModel.parameters`."""

    names: tuple[str, ...]
    matrix: NDArray[np.float64]

    def __post_init__(self) -> None:
        if isinstance(self.names, (str, bytes)) or not all(isinstance(n, str) for n in np.atleast_1d(np.asarray(self.names, dtype=object)).ravel()):
            raise InvalidInputError(f"`names` must be a sequence of parameter paths (str), got {show(self.names)}")
        try:
            m = np.asarray(self.matrix, dtype=float)
        except (TypeError, ValueError, OverflowError) as exc:
            raise InvalidInputError(f"`matrix` must be a numeric matrix: {exc}") from None
        n = len(self.names)
        if m.shape != (n, n):
            raise InvalidInputError(f"`matrix` must be {n} x {n} for {n} names, got shape {m.shape}")
        if not np.all(np.isfinite(m)) or not np.allclose(m, m.T, rtol=1e-8, atol=0):
            raise InvalidInputError("`matrix` must be finite and symmetric")
        object.__setattr__(self, "names", tuple(self.names))
        object.__setattr__(self, "matrix", m)

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Covariance) and self.names == other.names and bool(np.array_equal(self.matrix, other.matrix))

    __hash__ = None  # type: ignore[assignment]

    def stderr(self) -> dict[str, float]:
        """Standard error of each parameter (SI)."""
        return {n: float(np.sqrt(max(self.matrix[i, i], 0.0))) for i, n in enumerate(self.names)}


#: Most models :meth:`AxisModel.sample` draws in one call (each is a validated model object).
MAX_SAMPLES = 1_000_000


@dataclass(frozen=True)
class AxisModel(NativeBacked):
    """A servo axis: plant, friction model, effects, units, covariance and provenance.

    Parameters
    ----------
    plant : Plant
        ``a / (s^2 + b s + c)`` with delay and force gain (``Plant.from_mass`` for a rigid body).
    friction : StaticFriction, GMS, MaxwellSlip, LuGre or None
    effects : Effects
    units : AxisUnits
    covariance : Covariance, optional
        Of the parameters named by :meth:`parameters` (SI).
    provenance : dict
        Where the model came from: package version, input files and columns, command.
    """

    _native: ClassVar[_gmsfric.AxisSpec]

    plant: Plant
    friction: FrictionModel | None = None
    effects: Effects = field(default_factory=Effects)
    units: AxisUnits = field(default_factory=AxisUnits)
    covariance: Covariance | None = None
    provenance: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not isinstance(self.plant, Plant):
            raise InvalidInputError(f"`plant` must be a Plant, got {type(self.plant).__name__}")
        if not isinstance(self.effects, Effects):
            raise InvalidInputError(f"`effects` must be an Effects, got {type(self.effects).__name__}")
        spec = _gmsfric.AxisSpec(self.plant._native, native_friction(self.friction), **self.effects.core_args())
        object.__setattr__(self, "_native", spec)
        object.__setattr__(self, "provenance", dict(self.provenance))

    def simulate(
        self,
        dt: float,
        *,
        reference: ArrayLike | None = None,
        controller: Controller | None = None,
        command: ArrayLike | None = None,
        **options: "Unpack[RunOptions]",
    ) -> "ClosedLoopResult":
        """Simulate this axis, effects in feedback: closed loop (``reference`` and ``controller``)
        or open loop (``command``, input units). Other keywords as :class:`~gmsfric.system.RunOptions`."""
        from .system import simulate_closed_loop

        if command is not None:
            if "feedforward" in options:
                raise InvalidInputError("give `command` or `feedforward`, not both")
            options["feedforward"] = command
        return simulate_closed_loop(self, None, controller, reference, dt, **options)

    def model_document(self) -> dict[str, Any]:
        """The model file's document (``save_model`` writes it; covariance and provenance included)."""
        return axis_document(self)

    # -- parameters ------------------------------------------------------------------------

    def parameters(self) -> dict[str, float]:
        """Every numeric parameter by path (``plant.a``, ``friction.stribeck.fc``,
        ``effects.position_force.coef.2`` ...), in SI."""
        out: dict[str, float] = {}
        _flatten(self.plant, "plant", out)
        if self.friction is not None:
            _flatten(self.friction, "friction", out)
        _flatten(self.effects, "effects", out)
        return out

    def with_parameters(self, values: Mapping[str, float]) -> "AxisModel":
        """A copy with the parameters at ``values`` (paths as :meth:`parameters`) changed; the
        new model is validated by the core like any other."""
        if not isinstance(values, Mapping):
            raise InvalidInputError(f"`values` must be a dict of parameter path -> value, got {show(values)}")
        model: Any = self
        for path, value in values.items():
            if not isinstance(path, str):
                raise InvalidInputError(f"`values` has a parameter path that is not a string: {show(path)}")
            model = _replace(model, path.split("."), number(path, value), path)
        return model  # type: ignore[no-any-return]

    def sample(self, n: int, *, seed: int | None = None) -> list["AxisModel"]:
        """``n`` models (at most ``MAX_SAMPLES``) with parameters drawn from the covariance (Monte
        Carlo over the identification's uncertainty). Draws that the core refuses (a negative
        stiffness, say) are drawn again."""
        if self.covariance is None:
            raise InvalidInputError("this model has no covariance to sample from")
        n = count("n", n, minimum=1, maximum=MAX_SAMPLES)
        rng = np.random.default_rng(None if seed is None else count("seed", seed, minimum=0))
        names = self.covariance.names
        base = self.parameters()
        missing = [k for k in names if k not in base]
        if missing:
            raise InvalidInputError(f"the covariance names parameters the model does not have: {missing}")
        mean = np.array([base[k] for k in names])
        out: list[AxisModel] = []
        attempts = 0
        while len(out) < n:
            attempts += 1
            if attempts > 20 * n + 100:
                raise InvalidInputError("most draws from the covariance give invalid models (negative levels or stiffnesses)")
            draw = rng.multivariate_normal(mean, self.covariance.matrix, method="eigh")
            try:
                out.append(self.with_parameters(dict(zip(names, draw))))
            except InvalidInputError:
                continue
        return out


def _flatten(obj: Any, prefix: str, out: dict[str, float]) -> None:
    if isinstance(obj, bool) or obj is None or isinstance(obj, str):
        return
    if isinstance(obj, (int, float)):
        out[prefix] = float(obj)
        return
    if isinstance(obj, tuple):
        for i, v in enumerate(obj):
            _flatten(v, f"{prefix}.{i}", out)
        return
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        for f in dataclasses.fields(obj):
            if f.name in ("units", "covariance", "provenance") or f.name == "kind" or f.name == "harmonics":
                continue
            _flatten(getattr(obj, f.name), f"{prefix}.{f.name}", out)


def _replace(obj: Any, path: Sequence[str], value: float, full: str) -> Any:
    if not path:
        return value
    head, *rest = path
    if isinstance(obj, tuple):
        try:
            i = int(head)
            items = list(obj)
            items[i] = _replace(items[i], rest, value, full)
        except (ValueError, IndexError):
            raise InvalidInputError(f"no parameter `{full}`") from None
        return tuple(items)
    if not (dataclasses.is_dataclass(obj) and not isinstance(obj, type)) or head not in {f.name for f in dataclasses.fields(obj)}:
        raise InvalidInputError(f"no parameter `{full}`")
    return dataclasses.replace(obj, **{head: _replace(getattr(obj, head), rest, value, full)})


__all__ = ["AxisModel", "AxisUnits", "Effects", "PositionSeries", "Drift", "Heating", "Compliance", "Covariance"]


# ------------------------------------------------------------------------------------------
# the model file (``save_model`` / ``load_model``, kind "axis")

#: Quantity of each parameter path's last component, for the model file's units.
_QUANTITY = {
    "plant.a": "plant_gain", "plant.b": "rate", "plant.c": "rate_squared", "plant.delay": "time", "plant.force_gain": "force_gain",
    "asymmetry.d_level": "force", "asymmetry.d_viscous": "damping",
    "drift.scale": "time", "drift.d_level": "force", "drift.d_viscous": "damping",
    "heating.tau": "time", "heating.d_level": "damping", "heating.d_viscous": "damping_per_velocity",
    "blocks.k": "stiffness", "blocks.w": "force",
    "compliance.mass": "mass", "compliance.fn_hz": "frequency", "compliance.zeta": "dimensionless",
    "series.lo": "position", "series.hi": "position", "series.periods": "position", "series.coef": "force",
    "series.q0": "position", "series.dq": "position", "series.values": "force", "series.harmonics": "dimensionless",
}

_FRICTION_QUANTITY = {"fc": "force", "fs": "force", "vs": "velocity", "delta": "dimensionless", "sigma": "damping", "offset": "force",
                      "v_linear": "velocity", "k": "stiffness", "w": "force", "alpha": "dimensionless", "c": "force_rate",
                      "sigma0": "stiffness", "sigma1": "damping", "sigma2": "damping"}


def parameter_quantity(path: str) -> str:
    """The quantity (:mod:`gmsfric.units`) of a parameter path of :meth:`AxisModel.parameters`."""
    parts = [p for p in path.split(".") if not p.isdigit()]
    if parts[0] == "plant":
        return _QUANTITY[".".join(parts[:2])]
    if parts[0] == "friction":
        return _FRICTION_QUANTITY[parts[-1]]
    if parts[0] == "effects" and len(parts) >= 2 and parts[1] == "asymmetry":
        return "force" if path.endswith(".0") else "damping"
    if parts[0] == "effects" and len(parts) >= 3:
        group = "series" if parts[1] in ("position_force", "position_friction") else parts[1]
        return _QUANTITY[f"{group}.{parts[2]}"]
    raise InvalidInputError(f"no parameter `{path}`")


def _encode_axis(m: AxisModel) -> tuple[dict[str, tuple[Any, str]], dict[str, Any]]:
    from .model_io import _kind_of

    params: dict[str, tuple[Any, str]] = {f"plant.{n}": (getattr(m.plant, n), _QUANTITY[f"plant.{n}"]) for n in ("a", "b", "c", "delay", "force_gain")}
    options: dict[str, Any] = {"command_unit": m.units.command}
    if m.friction is not None:
        mk = _kind_of(m.friction)
        fp, fo = mk.encode(m.friction)
        params.update({f"friction.{k}": v for k, v in fp.items()})
        options["friction"] = mk.kind
        options.update({f"friction.{k}": v for k, v in fo.items()})
    e = m.effects
    if e.asymmetry is not None:
        params["effects.asymmetry.d_level"] = (e.asymmetry[0], "force")
        params["effects.asymmetry.d_viscous"] = (e.asymmetry[1], "damping")
    for name in ("position_force", "position_friction"):
        s: PositionSeries | None = getattr(e, name)
        if s is None:
            continue
        options[f"effects.{name}"] = s.kind
        if s.kind == "legendre":
            options[f"effects.{name}.beyond"] = s.beyond
        fields = {"legendre": ("lo", "hi", "coef"), "fourier": ("periods", "harmonics", "coef"), "table": ("q0", "dq", "values")}[s.kind]
        for f in fields:
            v = getattr(s, f)
            params[f"effects.{name}.{f}"] = (list(v) if isinstance(v, tuple) else float(v), _QUANTITY[f"series.{f}"])
    for name, fields in (("drift", ("scale", "d_level", "d_viscous")), ("heating", ("tau", "d_level", "d_viscous")), ("compliance", ("mass", "fn_hz", "zeta"))):
        obj = getattr(e, name)
        if obj is not None:
            for f in fields:
                params[f"effects.{name}.{f}"] = (getattr(obj, f), _QUANTITY[f"{name}.{f}"])
    if e.drift is not None:
        options["effects.drift"] = e.drift.shape
    if e.blocks is not None:
        params["effects.blocks.k"] = (list(e.blocks.k), "stiffness")
        params["effects.blocks.w"] = (list(e.blocks.w), "force")
    return params, options


def _decode_axis(p: Any) -> AxisModel:
    from . import units as _units
    from .model_io import _KINDS, ModelFormatError, Parameters

    doc = p.document
    options = doc.get("options")
    options = {} if options is None else options
    if not isinstance(options, Mapping):
        raise ModelFormatError(f"{p.source}: \"options\" must be an object, got {show(options)}")
    provenance = doc.get("provenance")
    provenance = {} if provenance is None else provenance
    if not isinstance(provenance, Mapping):
        raise ModelFormatError(f"{p.source}: \"provenance\" must be an object, got {show(provenance)}")
    rotary = p.rotary
    from .model_io import _drive_of

    command = options.get("command_unit", "V")
    if not isinstance(command, str):
        raise ModelFormatError(f"{p.source}: \"options\".\"command_unit\" must be a unit string, got {show(command)}")
    try:
        command_drive = _units.drive_base(command, name="command_unit")
    except _units.UnitError as exc:
        raise ModelFormatError(f"{p.source}: {exc}") from None
    drive = _drive_of(p, "plant.")
    if drive != command_drive:
        raise ModelFormatError(f"{p.source}: the command is in {command} but the plant's gains are per {drive}: "
                               "a force gain per one drive applied to a command in another would scale the friction")
    # a force command (the run gave its drive as a force) keeps its drive on the plant; a volt
    # or ampere axis model keeps the plant as it was built
    plant = Plant(*(p.get(f"plant.{n}", _QUANTITY[f"plant.{n}"]) for n in ("a", "b", "c", "delay", "force_gain")))
    if drive in ("N", "N m"):
        plant = dataclasses.replace(plant, drive=drive)
    friction = None
    fkind = options.get("friction")
    if fkind is not None:
        if not isinstance(fkind, str) or fkind not in _KINDS or fkind in ("axis", "plant"):
            raise ModelFormatError(f"{p.source}: unknown friction kind {show(fkind)}")
        sub = {
            "kind": fkind,
            "axis": "rotary" if rotary else "linear",
            "parameters": {k[len("friction."):]: v for k, v in doc["parameters"].items() if k.startswith("friction.")},
            "options": {k[len("friction."):]: v for k, v in options.items() if k.startswith("friction.")},
        }
        fp = Parameters(sub, f"{p.source} (friction)")
        friction = _KINDS[fkind].decode(fp)
        if getattr(friction, "rotary", False):
            # inside an axis model its units state the axis; its parts stay as the loop builds them
            friction = dataclasses.replace(friction, rotary=False)
        fp.check_all_used()
        p.used.update(f"friction.{n}" for n in fp.used)
    kw: dict[str, Any] = {}
    if p.has("effects.asymmetry.d_level"):
        kw["asymmetry"] = (p.get("effects.asymmetry.d_level", "force"), p.get("effects.asymmetry.d_viscous", "damping"))
    for name in ("position_force", "position_friction"):
        kind = options.get(f"effects.{name}")
        if kind is None:
            continue
        g = lambda f, vector=False: p.get(f"effects.{name}.{f}", _QUANTITY[f"series.{f}"], vector=vector)  # noqa: E731
        if kind == "legendre":
            # files written before the option existed held the series beyond the travel
            beyond = options.get(f"effects.{name}.beyond", "hold")
            if beyond not in ("hold", "linear"):
                raise ModelFormatError(f"{p.source}: \"options\".\"effects.{name}.beyond\" must be \"hold\" or \"linear\", got {show(beyond)}")
            kw[name] = PositionSeries.legendre(g("lo"), g("hi"), g("coef", True), beyond)
        elif kind == "fourier":
            kw[name] = PositionSeries.fourier(g("periods", True), int(round(g("harmonics"))), g("coef", True))
        elif kind == "table":
            q0, dq, values = g("q0"), g("dq"), g("values", True)
            kw[name] = PositionSeries("table", q0=q0, dq=dq, values=tuple(values))
        else:
            raise ModelFormatError(f"{p.source}: unknown series kind {kind!r} for {name}")
    if p.has("effects.drift.scale"):
        shape = options.get("effects.drift", "linear")
        kw["drift"] = Drift(shape, *(p.get(f"effects.drift.{f}", _QUANTITY[f"drift.{f}"]) for f in ("scale", "d_level", "d_viscous")))
    if p.has("effects.heating.tau"):
        kw["heating"] = Heating(*(p.get(f"effects.heating.{f}", _QUANTITY[f"heating.{f}"]) for f in ("tau", "d_level", "d_viscous")))
    if p.has("effects.compliance.mass"):
        kw["compliance"] = Compliance(*(p.get(f"effects.compliance.{f}", _QUANTITY[f"compliance.{f}"]) for f in ("mass", "fn_hz", "zeta")))
    if p.has("effects.blocks.k"):
        kw["blocks"] = MaxwellSlip(p.get("effects.blocks.k", "stiffness", vector=True), p.get("effects.blocks.w", "force", vector=True))
    cov = None
    c = doc.get("covariance")
    if c is not None:
        try:
            names = [str(n) for n in c["names"]]
            f = np.array([_units.factor(str(u), parameter_quantity(n), rotary=rotary, name=f"covariance unit of {n}") for n, u in zip(names, c["units"])])
            cov = Covariance(tuple(names), np.asarray(c["matrix"], dtype=float) * np.outer(f, f))
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelFormatError(f"{p.source}: malformed covariance: {exc}") from None
    units = AxisUnits("rotary" if rotary else "linear", command)
    return AxisModel(plant, friction, Effects(**kw), units, cov, dict(provenance))


def axis_document(model: AxisModel, provenance: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The model file's document of ``model`` (its covariance and provenance included)."""
    from . import units as _units
    from .model_io import model_to_dict

    rotary = model.units.kind == "rotary"
    drive = _units.drive_base(model.units.command, name="units.command")
    cov = None
    if model.covariance is not None:
        names = list(model.covariance.names)
        cov = (names, model.covariance.matrix, [_units.si_unit(parameter_quantity(n), rotary, drive=drive) for n in names])
    return model_to_dict(model, rotary=rotary, drive=drive, covariance=cov, provenance={**dict(model.provenance), **dict(provenance or {})})


def _register() -> None:
    from .model_io import register_kind

    register_kind("axis", AxisModel, _encode_axis, _decode_axis, replace=True)


_register()
