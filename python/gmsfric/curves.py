"""The friction curves in numpy, one implementation for the Python side: the Stribeck curve, the
static friction map (paper eq. 2) and the Maxwell-slip / GMS virgin curve.

Any consistent units.  The compiled core has its own (scalar) implementation for the simulation;
these are for fitting, plotting and regression columns.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["stribeck_shape", "stribeck", "static_map", "virgin_curve"]


def stribeck_shape(v: ArrayLike, vs: float, delta: float = 1.0) -> NDArray[np.float64]:
    """``exp(-|v/vs|^delta)``: 1 at rest, 0 in full sliding."""
    v = np.asarray(v, dtype=float)
    return np.exp(-np.abs(v / vs) ** delta)  # type: ignore[no-any-return]


def stribeck(v: ArrayLike, fc: float, fs: float, vs: float, delta: float = 1.0) -> NDArray[np.float64]:
    """The Stribeck curve ``s(v) = fc + (fs - fc) exp(-|v/vs|^delta)``."""
    return fc + (fs - fc) * stribeck_shape(v, vs, delta)  # type: ignore[no-any-return]


def static_map(v: ArrayLike, fc: float, fs: float, vs: float, delta: float = 1.0, sigma: float = 0.0, *, offset: float = 0.0,
               v_linear: float = 0.0) -> NDArray[np.float64]:
    """The static friction map ``F(v) = sign(v) s(v) + sigma v + offset`` (paper eq. 2).

    ``F(0) = offset``.  With ``v_linear > 0`` the map is the straight line through the origin
    and ``F(v_linear)`` (plus the offset) for ``|v| < v_linear``, as Simulink friction blocks
    implement it.
    """
    v = np.asarray(v, dtype=float)
    f = np.sign(v) * stribeck(v, fc, fs, vs, delta) + sigma * v
    if v_linear > 0:
        slope = (float(stribeck(v_linear, fc, fs, vs, delta)) + sigma * v_linear) / v_linear
        f = np.where(np.abs(v) < v_linear, slope * v, f)
    return f + offset if offset else f  # type: ignore[no-any-return]


def virgin_curve(x: ArrayLike, k: ArrayLike, w: ArrayLike) -> NDArray[np.float64]:
    """Virgin curve of elasto-slip blocks ``sign(x) sum_i min(k_i |x|, w_i)``: block ``i`` of
    stiffness ``k_i`` breaks at the force ``w_i`` (its displacement ``w_i / k_i``)."""
    x = np.asarray(x, dtype=float)
    k = np.asarray(k, dtype=float)
    w = np.asarray(w, dtype=float)
    flat = np.abs(x).reshape(1, -1)
    return (np.sign(x).reshape(-1) * np.minimum(k[:, None] * flat, w[:, None]).sum(axis=0)).reshape(x.shape)  # type: ignore[no-any-return]
