"""Stubs of the compiled core binding (``crates/gms-py``)."""

from typing import Callable, Optional, final

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ControllerSpec",
    "FrictionSpec",
    "GmsfricError",
    "InvalidInputError",
    "SimulationError",
    "discretize_plant",
    "simulate_closed_loop",
    "simulate_closed_loop_batch",
    "simulate_friction_batch",
    "simulate_open_loop",
    "static_map_force",
    "__version__",
]

__version__: str

class GmsfricError(Exception): ...
class InvalidInputError(GmsfricError, ValueError): ...
class SimulationError(GmsfricError, RuntimeError): ...

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
    def simulate_position(self, t: NDArray[np.float64], x: NDArray[np.float64]) -> NDArray[np.float64]: ...
    def simulate_velocity(self, dt: float, v: NDArray[np.float64]) -> NDArray[np.float64]: ...

@final
class ControllerSpec:
    @staticmethod
    def pid(kp: float, ki: float, kd: float, tf: float, u_min: float, u_max: float, dt: float) -> ControllerSpec: ...
    @staticmethod
    def cascade(kp: float, kv: float, u_min: float, u_max: float, dt: float) -> ControllerSpec: ...
    @staticmethod
    def pid_dob(
        kp: float, ki: float, kd: float, tf: float, u_min: float, u_max: float, dt: float, a: float, b: float, c: float, delay: float, dob_cutoff_hz: float
    ) -> ControllerSpec: ...

def static_map_force(
    fc: float, fs: float, vs: float, delta: float, sigma: float, v: NDArray[np.float64], offset: float = 0.0, v_linear: float = 0.0
) -> NDArray[np.float64]: ...
def simulate_closed_loop(
    plant_params: tuple[float, float, float, float, float],
    friction: Optional[FrictionSpec],
    controller: ControllerSpec,
    reference: NDArray[np.float64],
    dt: float,
    feedforward: Optional[NDArray[np.float64]] = None,
    input_disturbance: Optional[NDArray[np.float64]] = None,
    load_force: Optional[NDArray[np.float64]] = None,
    measurement_noise: Optional[NDArray[np.float64]] = None,
    quantization: float = 0.0,
    drive_min: float = ...,
    drive_max: float = ...,
    initial_position: Optional[float] = None,
    initial_velocity: float = 0.0,
) -> dict[str, Optional[NDArray[np.float64]]]: ...
def simulate_open_loop(
    plant_params: tuple[float, float, float, float, float], dt: float, u: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
def discretize_plant(
    plant_params: tuple[float, float, float, float, float], dt: float
) -> tuple[list[float], list[float], list[float], list[float], int]: ...
def simulate_closed_loop_batch(
    plant_params: list[tuple[float, float, float, float, float]],
    frictions: list[Optional[FrictionSpec]],
    controllers: list[ControllerSpec],
    reference: NDArray[np.float64],
    dt: float,
    feedforward: Optional[NDArray[np.float64]] = None,
    input_disturbance: Optional[NDArray[np.float64]] = None,
    load_force: Optional[NDArray[np.float64]] = None,
    measurement_noise: Optional[NDArray[np.float64]] = None,
    quantization: float = 0.0,
    drive_min: float = ...,
    drive_max: float = ...,
    initial_position: Optional[float] = None,
    initial_velocity: float = 0.0,
    threads: Optional[int] = None,
    progress: Optional[Callable[[int, int], object]] = None,
    poll_interval: float = 0.2,
) -> dict[str, NDArray[np.float64]]: ...
def simulate_friction_batch(
    models: list[FrictionSpec],
    t: NDArray[np.float64],
    position: NDArray[np.float64],
    threads: Optional[int] = None,
    progress: Optional[Callable[[int, int], object]] = None,
    poll_interval: float = 0.2,
) -> NDArray[np.float64]: ...
