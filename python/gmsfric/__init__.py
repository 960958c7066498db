"""gmsfric: friction identification and fast simulation of precision servo axes.

The compiled core (``gmsfric._gmsfric``, Rust) integrates the stiff friction models and the
delayed plant; this package exposes the models, identification, analysis and plotting.
"""

from __future__ import annotations

from ._gmsfric import __version__
from .axis import AxisModel, AxisUnits, Compliance, Covariance, Drift, Effects, Heating, PositionSeries
from .errors import DataError, GmsfricError, IdentificationError, InvalidInputError, OutputPathError, ResourceError, SimulationError
from .models import GMS, LuGre, MaxwellSlip, StaticFriction, Stribeck, simulate_friction
from .model_io import load_model, save_model
from .system import PID, PIDDOB, Cascade, ClosedLoopResult, Plant, RunOptions, simulate_closed_loop

# Subpackages load on first use (they pull in scipy): ``gmsfric.identify.fit_static_map(...)``.
_SUBMODULES = ("identify", "loop", "glitch", "batch", "presets", "io", "plotting", "demo", "units", "results", "model_io", "curves", "output_error")


def __getattr__(name: str) -> object:
    if name in _SUBMODULES:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

__all__ = [
    "__version__",
    "Stribeck",
    "StaticFriction",
    "GMS",
    "LuGre",
    "MaxwellSlip",
    "simulate_friction",
    "Plant",
    "PID",
    "PIDDOB",
    "Cascade",
    "ClosedLoopResult",
    "simulate_closed_loop",
    "RunOptions",
    "AxisModel",
    "AxisUnits",
    "Effects",
    "PositionSeries",
    "Drift",
    "Heating",
    "Compliance",
    "Covariance",
    "save_model",
    "load_model",
    "GmsfricError",
    "ResourceError",
    "InvalidInputError",
    "SimulationError",
    "DataError",
    "OutputPathError",
    "IdentificationError",
    *_SUBMODULES,
]
