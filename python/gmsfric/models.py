"""Friction models: the Stribeck curve, the static map, GMS, Maxwell-slip and LuGre.

All quantities are SI (m, m/s, N, s).  Each model is an immutable value object validated on
construction; the compiled core (``gmsfric._gmsfric``) does the simulation.

Interpretation of the paper's garbled GMS equation (eq. 4): a slipping block relaxes towards
``sign(v) * alpha_i * s(v)``.  ``slip_law="time"`` (default, Al-Bender, Lampaert & Swevers 2005)
uses ``dF_i/dt = c * (sign(v) alpha_i - F_i / s(v))``, i.e. a rate ``c / s(v)`` with ``c`` in N/s;
``slip_law="displacement"`` uses ``dF_i/dx = c (sign(v) alpha_i s(v) - F_i)``, a rate ``c |v|``
with ``c`` in 1/m.  Blocks stick (``dF_i/dt = k_i v``) until ``|F_i|`` reaches ``alpha_i s(v)``
and return to sticking when the velocity reverses or stops.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal, Sequence, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _gmsfric
from ._validate import as_array, finite, non_negative, positive, same_length
from .errors import InvalidInputError

SlipLaw = Literal["time", "displacement"]


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
        for name in ("fc", "fs"):
            object.__setattr__(self, name, non_negative(name, getattr(self, name)))
        object.__setattr__(self, "vs", positive("vs", self.vs))
        object.__setattr__(self, "delta", positive("delta", self.delta))

    def __call__(self, v: ArrayLike) -> NDArray[np.float64]:
        """Evaluate ``s(v)`` (N) on velocities ``v`` (m/s)."""
        v = as_array("v", v)
        return self.fc + (self.fs - self.fc) * np.exp(-np.abs(v / self.vs) ** self.delta)

    @property
    def params(self) -> tuple[float, float, float, float]:
        return (self.fc, self.fs, self.vs, self.delta)


@dataclass(frozen=True)
class StaticFriction:
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
    """

    stribeck: Stribeck
    sigma: float = 0.0
    offset: float = 0.0
    v_linear: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.stribeck, Stribeck):
            raise InvalidInputError(f"`stribeck` must be a Stribeck, got {type(self.stribeck).__name__}")
        object.__setattr__(self, "sigma", non_negative("sigma", self.sigma))
        object.__setattr__(self, "offset", finite("offset", self.offset))
        object.__setattr__(self, "v_linear", non_negative("v_linear", self.v_linear))

    def force(self, v: ArrayLike) -> NDArray[np.float64]:
        """Friction force (N) at velocities ``v`` (m/s); ``F(0) = offset``."""
        return _gmsfric.static_map_force(*self.stribeck.params, self.sigma, as_array("v", v), self.offset, self.v_linear)

    @cached_property
    def _native(self) -> _gmsfric.FrictionSpec:
        return _gmsfric.FrictionSpec.static_map(*self.stribeck.params, self.sigma, self.offset, self.v_linear)


def _positive_vector(name: str, values: ArrayLike) -> tuple[float, ...]:
    arr = as_array(name, values)
    bad = np.flatnonzero(arr <= 0)
    if bad.size:
        raise InvalidInputError(f"`{name}` must be > 0 everywhere, got {arr[bad[0]]} at index {bad[0]} (negative or zero stiffness)")
    return tuple(float(x) for x in arr)


@dataclass(frozen=True)
class GMS:
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
    """

    stribeck: Stribeck
    k: Sequence[float]
    alpha: Sequence[float]
    c: float
    sigma: float = 0.0
    slip_law: SlipLaw = "time"

    def __post_init__(self) -> None:
        if not isinstance(self.stribeck, Stribeck):
            raise InvalidInputError(f"`stribeck` must be a Stribeck, got {type(self.stribeck).__name__}")
        k = _positive_vector("k", self.k)
        alpha = as_array("alpha", self.alpha)
        same_length("alpha", alpha, "k", len(k))
        if np.any(alpha < 0):
            raise InvalidInputError(f"`alpha` must be >= 0, got {alpha.min()}")
        if abs(alpha.sum() - 1.0) > 1e-6:
            raise InvalidInputError(
                f"`alpha` must sum to 1 (fractions), got {alpha.sum():.6g}; use GMS.from_break_forces for forces in N"
            )
        object.__setattr__(self, "k", k)
        object.__setattr__(self, "alpha", tuple(float(a) for a in alpha))
        object.__setattr__(self, "c", positive("c", self.c))
        object.__setattr__(self, "sigma", non_negative("sigma", self.sigma))
        if self.slip_law not in ("time", "displacement"):
            raise InvalidInputError(f"`slip_law` must be 'time' or 'displacement', got {self.slip_law!r}")

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
    ) -> "GMS":
        """Build from block break forces ``w_i`` (N) as printed in the paper's Table 2.

        ``alpha_i = w_i / sum(w)`` always.  ``scale`` decides the friction level:
        ``"stribeck"`` keeps ``stribeck`` as given (blocks break at ``alpha_i s(v)``);
        ``"sum"`` rescales the Stribeck curve so that ``s(0) = sum(w)`` (the paper's eq. 6:
        ``sum W_i`` is the break-away force), keeping its ``fc/fs`` ratio.  Without a
        ``stribeck`` the level is constant at ``sum(w)`` (a Maxwell-slip-like GMS).
        """
        w_arr = as_array("w", w)
        if np.any(w_arr < 0) or w_arr.sum() <= 0:
            raise InvalidInputError("`w` (break forces) must be >= 0 with a positive sum")
        total = float(w_arr.sum())
        if stribeck is None:
            stribeck = Stribeck(total, total, 1.0, 1.0)
        elif scale == "sum":
            ratio = total / stribeck.fs if stribeck.fs > 0 else 1.0
            stribeck = Stribeck(stribeck.fc * ratio, total, stribeck.vs, stribeck.delta)
        elif scale != "stribeck":
            raise InvalidInputError(f"`scale` must be 'stribeck' or 'sum', got {scale!r}")
        return cls(stribeck, k, w_arr / total, c, sigma, slip_law)

    @property
    def n_blocks(self) -> int:
        return len(self.k)

    @property
    def break_forces(self) -> NDArray[np.float64]:
        """Block break forces at rest ``w_i = alpha_i s(0)`` (N)."""
        return np.asarray(self.alpha) * self.stribeck.fs

    def virgin_curve(self, x: ArrayLike) -> NDArray[np.float64]:
        """Quasi-static virgin curve ``sign(x) sum_i min(k_i |x|, alpha_i s(0))`` (N)."""
        x = as_array("x", x)
        k = np.asarray(self.k)[:, None]
        w = self.break_forces[:, None]
        return np.sign(x) * np.minimum(k * np.abs(x)[None, :], w).sum(axis=0)

    def static_map(self) -> StaticFriction:
        """The static map the model settles on at constant velocity."""
        return StaticFriction(self.stribeck, self.sigma)

    @cached_property
    def _native(self) -> _gmsfric.FrictionSpec:
        return _gmsfric.FrictionSpec.gms(*self.stribeck.params, list(self.k), list(self.alpha), self.c, self.sigma, self.slip_law)


@dataclass(frozen=True)
class MaxwellSlip:
    """Plain Maxwell-slip: blocks of stiffness ``k_i`` (N/m) that slip instantly at ``w_i`` (N)."""

    k: Sequence[float]
    w: Sequence[float]
    sigma: float = 0.0

    def __post_init__(self) -> None:
        k = _positive_vector("k", self.k)
        w = as_array("w", self.w)
        same_length("w", w, "k", len(k))
        if np.any(w < 0):
            raise InvalidInputError(f"`w` must be >= 0, got {w.min()}")
        object.__setattr__(self, "k", k)
        object.__setattr__(self, "w", tuple(float(x) for x in w))
        object.__setattr__(self, "sigma", non_negative("sigma", self.sigma))

    def virgin_curve(self, x: ArrayLike) -> NDArray[np.float64]:
        """``sign(x) sum_i min(k_i |x|, w_i)`` (N)."""
        x = as_array("x", x)
        return np.sign(x) * np.minimum(np.asarray(self.k)[:, None] * np.abs(x)[None, :], np.asarray(self.w)[:, None]).sum(axis=0)

    @cached_property
    def _native(self) -> _gmsfric.FrictionSpec:
        return _gmsfric.FrictionSpec.maxwell_slip(list(self.k), list(self.w), self.sigma)


@dataclass(frozen=True)
class LuGre:
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
    """

    stribeck: Stribeck
    sigma0: float
    sigma1: float = 0.0
    sigma2: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.stribeck, Stribeck):
            raise InvalidInputError(f"`stribeck` must be a Stribeck, got {type(self.stribeck).__name__}")
        object.__setattr__(self, "sigma0", positive("sigma0", self.sigma0))
        object.__setattr__(self, "sigma1", non_negative("sigma1", self.sigma1))
        object.__setattr__(self, "sigma2", non_negative("sigma2", self.sigma2))

    @cached_property
    def _native(self) -> _gmsfric.FrictionSpec:
        return _gmsfric.FrictionSpec.lugre(*self.stribeck.params, self.sigma0, self.sigma1, self.sigma2)


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
    assert spec is not None
    t_arr = as_array("t", t, min_len=2)
    if (position is None) == (velocity is None):
        raise InvalidInputError("give exactly one of `position` or `velocity`")
    if position is None:
        v = as_array("velocity", velocity)  # type: ignore[arg-type]
        same_length("velocity", v, "t", t_arr.size)
        x = np.concatenate(([0.0], np.cumsum(v[1:] * np.diff(t_arr))))
    else:
        x = as_array("position", position)
        same_length("position", x, "t", t_arr.size)
    return spec.simulate_position(t_arr, x)
