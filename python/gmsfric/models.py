"""Friction models: the Stribeck curve, the static map, GMS, Maxwell-slip and LuGre.

All quantities are SI (m, m/s, N, s; rad, rad/s, N m for rotary axes).  Each model is an
immutable value object validated on construction by the compiled core (``gmsfric._gmsfric``),
which holds every argument rule and does the simulation; this module only coerces numbers.

Interpretation of the paper's garbled GMS equation (eq. 4): a slipping block relaxes towards
``sign(v) * alpha_i * s(v)``.  ``slip_law="time"`` (default, Al-Bender, Lampaert & Swevers 2005)
uses ``dF_i/dt = c * (sign(v) alpha_i - F_i / s(v))``, i.e. a rate ``c / s(v)`` with ``c`` in N/s;
``slip_law="displacement"`` uses ``dF_i/dx = c (sign(v) alpha_i s(v) - F_i)``, a rate ``c |v|``
with ``c`` in 1/m.  Blocks stick (``dF_i/dt = k_i v``) until ``|F_i|`` reaches ``alpha_i s(v)``
and return to sticking when the velocity reverses or stops.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Literal, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric, curves
from ._validate import as_array, choice, number, same_length
from .errors import InvalidInputError

SlipLaw = Literal["time", "displacement"]


class NativeBacked:
    """Mixin of the frozen model classes whose core twin (``_native``) is built and validated in
    ``__post_init__``: the twin is left out of pickles (it cannot be pickled) and rebuilt on
    unpickling, so models travel to worker processes (``concurrent.futures``, dask)."""

    def __getstate__(self) -> dict[str, object]:
        state = dict(self.__dict__)
        state.pop("_native", None)
        return state

    def __setstate__(self, state: dict[str, object]) -> None:
        for key, value in state.items():
            object.__setattr__(self, key, value)
        self.__post_init__()  # type: ignore[attr-defined]


@dataclass(frozen=True)
class Stribeck:
    """Stribeck curve ``s(v) = fc + (fs - fc) exp(-|v/vs|^delta)`` (paper eq. 2).

    Parameters
    ----------
    fc : float
        Coulomb level (N), ``s(inf)``.
    fs : float
        Static (break-away) level (N), ``s(0)``.
    vs : float
        Stribeck velocity (m/s).
    delta : float, optional
        Shape exponent (1: exponential, 2: Gaussian).
    """

    fc: float
    fs: float
    vs: float
    delta: float = 1.0

    def __post_init__(self) -> None:
        for name in ("fc", "fs", "vs", "delta"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        # The core holds the rules (fc, fs >= 0; vs, delta > 0): a map with this curve checks them.
        _gmsfric.FrictionSpec.static_map(*self.params, 0.0)

    def __call__(self, v: ArrayLike) -> NDArray[np.float64]:
        """Evaluate ``s(v)`` (N) on velocities ``v`` (m/s)."""
        return curves.stribeck(as_array("v", v), *self.params)

    @property
    def params(self) -> tuple[float, float, float, float]:
        return (self.fc, self.fs, self.vs, self.delta)


@dataclass(frozen=True)
class StaticFriction(NativeBacked):
    """Static friction map ``F(v) = sign(v) s(v) + sigma v + offset`` (paper eq. 2).

    In closed-loop simulation the map is set-valued at ``v = 0`` (stiction): the contact sticks
    while the force needed to hold it is below ``s(0)``.

    Parameters
    ----------
    stribeck : Stribeck
    sigma : float, optional
        Viscous coefficient (N s/m).
    offset : float, optional
        Constant force independent of motion (N).
    v_linear : float, optional
        Linear-region velocity threshold (m/s), as Simulink/Simscape friction blocks implement a
        static map: for ``|v| < v_linear`` the force is the line through the origin and
        ``F(v_linear)``, so the contact can never stick.  ``0`` (default) keeps true stiction.
    rotary : bool, optional (keyword)
        The model is of a rotary axis: the same numbers in rad, rad/s, N m, N m/rad ... instead of
        m, m/s, N, N/m.  Saved in the model file's ``"axis"`` and read back by ``load_model``; an
        angle is never a length, so models of the two kinds are never mixed.
    """

    _native: ClassVar[_gmsfric.FrictionSpec]

    stribeck: Stribeck
    sigma: float = 0.0
    offset: float = 0.0
    v_linear: float = 0.0
    rotary: bool = field(default=False, kw_only=True)

    def __post_init__(self) -> None:
        _check_type("stribeck", self.stribeck, Stribeck)
        _check_rotary(self.rotary)
        for name in ("sigma", "offset", "v_linear"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        object.__setattr__(self, "_native", _gmsfric.FrictionSpec.static_map(*self.stribeck.params, self.sigma, self.offset, self.v_linear))

    def force(self, v: ArrayLike) -> NDArray[np.float64]:
        """Friction force (N) at velocities ``v`` (m/s); ``F(0) = offset``."""
        return self._native.static_force(as_array("v", v))


def _check_rotary(rotary: object) -> None:
    if not isinstance(rotary, (bool, np.bool_)):
        raise InvalidInputError(f"`rotary` must be True or False, got {type(rotary).__name__}")


def axis_name(model: object) -> str:
    """``"rotary"`` or ``"linear"``: the axis kind a model (or plant) is of."""
    return "rotary" if getattr(model, "rotary", False) else "linear"


def _check_type(name: str, value: object, kind: type) -> None:
    if not isinstance(value, kind):
        raise InvalidInputError(f"`{name}` must be a {kind.__name__}, got {type(value).__name__}")


def _vector(name: str, values: ArrayLike) -> tuple[float, ...]:
    return tuple(float(x) for x in as_array(name, values))


@dataclass(frozen=True)
class GMS(NativeBacked):
    """Generalized Maxwell-slip model with N elasto-slip blocks (paper eqs. 3-5).

    Parameters
    ----------
    stribeck : Stribeck
        Steady sliding level ``s(v)`` shared by all blocks.
    k : array_like
        Block stiffnesses ``k_i`` (N/m), all > 0.
    alpha : array_like
        Block fractions ``alpha_i`` (non-negative, summing to 1): block ``i`` breaks at
        ``alpha_i s(v)``.  Use :meth:`from_break_forces` for the paper's Table 2, which prints
        alpha in N.
    c : float
        Slip attraction parameter (N/s for ``slip_law="time"``, 1/m for ``"displacement"``).
    sigma : float, optional
        Viscous coefficient (N s/m).
    slip_law : {"time", "displacement"}
        Reading of the paper's eq. 4, see the module docstring.
    rotary : bool, optional (keyword)
        The model is of a rotary axis: the same numbers in rad, rad/s, N m, N m/rad ... instead of
        m, m/s, N, N/m.  Saved in the model file's ``"axis"`` and read back by ``load_model``; an
        angle is never a length, so models of the two kinds are never mixed.
    """

    _native: ClassVar[_gmsfric.FrictionSpec]

    stribeck: Stribeck
    k: Sequence[float]
    alpha: Sequence[float]
    c: float
    sigma: float = 0.0
    slip_law: SlipLaw = "time"
    rotary: bool = field(default=False, kw_only=True)

    def __post_init__(self) -> None:
        _check_type("stribeck", self.stribeck, Stribeck)
        _check_rotary(self.rotary)
        object.__setattr__(self, "k", _vector("k", self.k))
        object.__setattr__(self, "alpha", _vector("alpha", self.alpha))
        object.__setattr__(self, "c", number("c", self.c))
        object.__setattr__(self, "sigma", number("sigma", self.sigma))
        choice("slip_law", self.slip_law, ("time", "displacement"))
        spec = _gmsfric.FrictionSpec.gms(*self.stribeck.params, list(self.k), list(self.alpha), self.c, self.sigma, self.slip_law)
        object.__setattr__(self, "_native", spec)

    @classmethod
    def from_break_forces(
        cls,
        k: ArrayLike,
        w: ArrayLike,
        c: float,
        *,
        stribeck: Stribeck | None = None,
        sigma: float = 0.0,
        slip_law: SlipLaw = "time",
        scale: Literal["stribeck", "sum"] = "stribeck",
        rotary: bool = False,
    ) -> "GMS":
        """Build from block break forces ``w_i`` (N) as printed in the paper's Table 2.

        ``alpha_i = w_i / sum(w)`` always.  ``scale`` decides the friction level:
        ``"stribeck"`` keeps ``stribeck`` as given (blocks break at ``alpha_i s(v)``);
        ``"sum"`` rescales the Stribeck curve so that ``s(0) = sum(w)`` (the paper's eq. 6:
        ``sum W_i`` is the break-away force), keeping its ``fc/fs`` ratio.  Without a
        ``stribeck`` the level is constant at ``sum(w)`` (a Maxwell-slip-like GMS).  ``rotary``:
        a rotary axis' model (N m, N m/rad).
        """
        choice("scale", scale, ("stribeck", "sum"))
        if stribeck is not None:
            _check_type("stribeck", stribeck, Stribeck)
        w_arr = as_array("w", w)
        if np.any(w_arr < 0) or not w_arr.sum() > 0:
            raise InvalidInputError("`w` (break forces) must be >= 0 with a positive sum")
        total = float(w_arr.sum())
        if stribeck is None:
            stribeck = Stribeck(total, total, 1.0, 1.0)
        elif scale == "sum":
            ratio = total / stribeck.fs if stribeck.fs > 0 else 1.0
            stribeck = Stribeck(stribeck.fc * ratio, total, stribeck.vs, stribeck.delta)

        return cls(stribeck, k, w_arr / total, c, sigma, slip_law, rotary=rotary)

    @property
    def n_blocks(self) -> int:
        return len(self.k)

    @property
    def break_forces(self) -> NDArray[np.float64]:
        """Block break forces at rest ``w_i = alpha_i s(0)`` (N)."""
        return np.asarray(self.alpha) * self.stribeck.fs

    def virgin_curve(self, x: ArrayLike) -> NDArray[np.float64]:
        """Quasi-static virgin curve ``sign(x) sum_i min(k_i |x|, alpha_i s(0))`` (N)."""
        return curves.virgin_curve(as_array("x", x), self.k, self.break_forces)

    def static_map(self) -> StaticFriction:
        """The static map the model settles on at constant velocity."""
        return StaticFriction(self.stribeck, self.sigma, rotary=self.rotary)


@dataclass(frozen=True)
class MaxwellSlip(NativeBacked):
    """Plain Maxwell-slip: blocks of stiffness ``k_i`` (N/m) that slip instantly at ``w_i`` (N);
    ``rotary=True`` (keyword): a rotary axis' blocks (N m/rad, N m)."""

    _native: ClassVar[_gmsfric.FrictionSpec]

    k: Sequence[float]
    w: Sequence[float]
    sigma: float = 0.0
    rotary: bool = field(default=False, kw_only=True)

    def __post_init__(self) -> None:
        _check_rotary(self.rotary)
        object.__setattr__(self, "k", _vector("k", self.k))
        object.__setattr__(self, "w", _vector("w", self.w))
        object.__setattr__(self, "sigma", number("sigma", self.sigma))
        object.__setattr__(self, "_native", _gmsfric.FrictionSpec.maxwell_slip(list(self.k), list(self.w), self.sigma))

    def virgin_curve(self, x: ArrayLike) -> NDArray[np.float64]:
        """``sign(x) sum_i min(k_i |x|, w_i)`` (N)."""
        return curves.virgin_curve(as_array("x", x), self.k, self.w)


@dataclass(frozen=True)
class LuGre(NativeBacked):
    """LuGre model ``dz/dt = v - sigma0 |v| z / s(v)``, ``F = sigma0 z + sigma1 dz/dt + sigma2 v``.

    Parameters
    ----------
    stribeck : Stribeck
    sigma0 : float
        Bristle stiffness (N/m).
    sigma1 : float
        Bristle damping (N s/m).
    sigma2 : float
        Viscous coefficient (N s/m).
    rotary : bool, optional (keyword)
        The model is of a rotary axis: the same numbers in rad, rad/s, N m, N m/rad ... instead of
        m, m/s, N, N/m.  Saved in the model file's ``"axis"`` and read back by ``load_model``; an
        angle is never a length, so models of the two kinds are never mixed.
    """

    _native: ClassVar[_gmsfric.FrictionSpec]

    stribeck: Stribeck
    sigma0: float
    sigma1: float = 0.0
    sigma2: float = 0.0
    rotary: bool = field(default=False, kw_only=True)

    def __post_init__(self) -> None:
        _check_type("stribeck", self.stribeck, Stribeck)
        _check_rotary(self.rotary)
        for name in ("sigma0", "sigma1", "sigma2"):
            object.__setattr__(self, name, number(name, getattr(self, name)))
        object.__setattr__(self, "_native", _gmsfric.FrictionSpec.lugre(*self.stribeck.params, self.sigma0, self.sigma1, self.sigma2))


FrictionModel = Union[StaticFriction, GMS, MaxwellSlip, LuGre]


def native_friction(model: FrictionModel | None, name: str = "friction") -> _gmsfric.FrictionSpec | None:
    """The compiled spec of a friction model (``None`` passes through)."""
    if model is None:
        return None
    spec = getattr(model, "_native", None)
    if not isinstance(spec, _gmsfric.FrictionSpec):
        raise InvalidInputError(f"`{name}` must be a gmsfric friction model (StaticFriction, GMS, MaxwellSlip, LuGre), got {type(model).__name__}")
    return spec


def simulate_friction(
    model: FrictionModel,
    t: ArrayLike,
    position: ArrayLike | None = None,
    *,
    velocity: ArrayLike | None = None,
) -> NDArray[np.float64]:
    """Friction force along a measured trajectory (friction-only simulation).

    Parameters
    ----------
    model : StaticFriction, GMS, MaxwellSlip or LuGre
    t : array_like
        Sample times (s), strictly increasing (non-uniform steps are fine).
    position : array_like, optional
        Position (m) at ``t``.  Read without copying when it is a contiguous float64 array.
    velocity : array_like, optional
        Instead of ``position``: velocity (m/s) held over ``(t[k-1], t[k]]``.

    Returns
    -------
    ndarray
        Force (N) at ``t``.  Models with memory start from the virgin state.
    """
    spec = native_friction(model, "model")
    if spec is None:
        raise InvalidInputError("`model` must be a gmsfric friction model (StaticFriction, GMS, MaxwellSlip, LuGre), got None")
    t_arr = as_array("t", t, min_len=2)
    if (position is None) == (velocity is None):
        raise InvalidInputError("give exactly one of `position` or `velocity`")
    if position is None:
        v = as_array("velocity", velocity)
        same_length("velocity", v, "t", t_arr.size)
        x = np.concatenate(([0.0], np.cumsum(v[1:] * np.diff(t_arr))))
        if not np.isfinite(x).all():
            raise InvalidInputError("`velocity` integrates to a non-finite position")
    else:
        x = as_array("position", position)
        same_length("position", x, "t", t_arr.size)
    return _gmsfric.simulate_friction([spec], t_arr, x.reshape(1, -1), 1)[0]
