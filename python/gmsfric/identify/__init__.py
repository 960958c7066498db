"""Identification of the paper's models, automatically and with uncertainty (issue 4)."""

from .frf import FRF, estimate_frf, fit_plant, plant_to_control
from .results import IdentificationResult
from .rig import VirtualRig, band_limited_noise
from .static_map import find_plateaus, fit_static_map, fit_static_map_from_run

__all__ = [
    "IdentificationResult",
    "fit_static_map",
    "fit_static_map_from_run",
    "find_plateaus",
    "FRF",
    "estimate_frf",
    "fit_plant",
    "plant_to_control",
    "VirtualRig",
    "band_limited_noise",
]
