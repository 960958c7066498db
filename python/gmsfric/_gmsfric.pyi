"""Stubs of the compiled core binding (``crates/gms-py``)."""

from typing import Any, Callable, Optional, final

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "AxisSpec",
    "ControllerSpec",
    "FrictionSpec",
    "PlantSpec",
    "GmsfricError",
    "InvalidInputError",
    "ResourceError",
    "SimulationError",
    "reference_data",
    "reference_values",
    "simulate",
    "simulate_friction",
    "__version__",
    "LANES",
]

__version__: str
#: Runs advanced together in one SIMD vector group by the batch kernel.
LANES: int

class GmsfricError(Exception): ...
class InvalidInputError(GmsfricError, ValueError): ...
class SimulationError(GmsfricError, RuntimeError): ...
class ResourceError(GmsfricError, MemoryError): ...

@final
class FrictionSpec:
    @staticmethod
    def static_map(
        fc: float, fs: float, vs: float, delta: float, sigma: float, offset: float = 0.0, v_linear: float = 0.0
    ) -> FrictionSpec: ...
    @staticmethod
    def gms(
        fc: float, fs: float, vs: float, delta: float, k: list[float], alpha: list[float], c: float, sigma: float, slip_law: str = "time"
    ) -> FrictionSpec: ...
    @staticmethod
    def maxwell_slip(k: list[float], w: list[float], sigma: float) -> FrictionSpec: ...
    @staticmethod
    def lugre(fc: float, fs: float, vs: float, delta: float, sigma0: float, sigma1: float, sigma2: float) -> FrictionSpec: ...
    def static_force(self, v: NDArray[np.float64]) -> NDArray[np.float64]: ...

@final
class ControllerSpec:
    @staticmethod
    def pid(kp: float, ki: float, kd: float, tf: float, u_min: float, u_max: float) -> ControllerSpec: ...
    @staticmethod
    def cascade(kp: float, kv: float, u_min: float, u_max: float) -> ControllerSpec: ...
    @staticmethod
    def pid_dob(
        kp: float, ki: float, kd: float, tf: float, u_min: float, u_max: float, a: float, b: float, c: float, delay: float, dob_cutoff_hz: float
    ) -> ControllerSpec: ...

@final
class PlantSpec:
    def __new__(cls, a: float, b: float, c: float, delay: float, force_gain: float) -> PlantSpec: ...
    def discretize(self, dt: float) -> tuple[list[float], list[float], list[float], list[float], int]: ...

@final
class AxisSpec:
    def __new__(
        cls,
        plant: PlantSpec,
        friction: Optional[FrictionSpec] = None,
        *,
        asymmetry: Optional[tuple[float, float]] = None,
        position_force: Optional[dict[str, Any]] = None,
        position_friction: Optional[dict[str, Any]] = None,
        drift: Optional[tuple[str, float, float, float]] = None,
        heating: Optional[tuple[float, float, float]] = None,
        blocks: Optional[tuple[list[float], list[float]]] = None,
        compliance: Optional[tuple[float, float, float]] = None,
    ) -> AxisSpec: ...

def simulate(
    axes: list[AxisSpec],
    controllers: list[Optional[ControllerSpec]],
    dt: float,
    inputs: dict[str, Any],
    record: list[str],
    every: int = 1,
    threads: Optional[int] = None,
    progress: Optional[Callable[[int, int], object]] = None,
    poll_interval: float = 0.2,
) -> dict[str, NDArray[np.float64]]: ...
def simulate_friction(
    models: list[FrictionSpec],
    t: NDArray[np.float64],
    position: NDArray[np.float64],
    threads: Optional[int] = None,
    progress: Optional[Callable[[int, int], object]] = None,
    poll_interval: float = 0.2,
) -> NDArray[np.float64]: ...
def reference_data() -> str: ...
def reference_values() -> list[tuple[str, list[float]]]: ...
