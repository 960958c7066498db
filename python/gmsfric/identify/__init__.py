"""Identification of the paper's models, automatically and with uncertainty.

Static map (eq. 2) from constant-velocity tests, GMS pre-sliding blocks from the virgin-curve
test (eq. 6), plant and delay from an FRF (eq. 1), automatic model revision (Section 4.1), and a
virtual rig that replays the paper's experiments on the Rust simulator.  See
``docs/identification.md``.
"""

from .frf import FRF, estimate_frf, fit_plant, plant_response, plant_to_control
from .paper import ReplaySettings, Table3Reading, replay_paper
from .presliding import build_virgin_curve, fit_presliding
from .results import IdentificationResult, Replay
from .revision import combined_frf, revise_plant
from .rig import VirtualRig, band_limited_noise
from .static_map import find_plateaus, fit_static_map, fit_static_map_from_run, static_map_curve

__all__ = [
    "IdentificationResult",
    "Replay",
    "fit_static_map",
    "fit_static_map_from_run",
    "find_plateaus",
    "static_map_curve",
    "fit_presliding",
    "build_virgin_curve",
    "FRF",
    "estimate_frf",
    "fit_plant",
    "plant_response",
    "plant_to_control",
    "revise_plant",
    "combined_frf",
    "VirtualRig",
    "band_limited_noise",
    "replay_paper",
    "ReplaySettings",
    "Table3Reading",
]
