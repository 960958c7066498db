"""gmsfric: friction identification and fast simulation of precision servo axes.

The compiled core (``gmsfric._gmsfric``, Rust) integrates the stiff friction models and the
delayed plant; this package exposes the models, identification, analysis and plotting.
"""

from __future__ import annotations

from ._gmsfric import __version__
from .errors import DataError, GmsfricError, IdentificationError, InvalidInputError, SimulationError
from .models import GMS, LuGre, MaxwellSlip, StaticFriction, Stribeck, simulate_friction
from .system import PID, Cascade, ClosedLoopResult, Plant, simulate_closed_loop

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
    "Cascade",
    "ClosedLoopResult",
    "simulate_closed_loop",
    "GmsfricError",
    "InvalidInputError",
    "SimulationError",
    "DataError",
    "IdentificationError",
]
