"""efdm-tracker engine: explicit physics-based deformable contour models.

Krinidis & Pitas, "2D Physics-Based Deformable Shape Models: Explicit
Governing Equations".  Coordinates are ``[x, y]`` pixels (x = column,
y = row), as in OpenCV.

Main entry points: :func:`deform` (equilibrium displacements under forces)
and :class:`Chain` (a contour model with static and dynamic updates).
"""

from typing import TYPE_CHECKING

from engine.chain import Chain, ChainState
from engine.deform import METHODS, deform
from engine.green import green_kernel, literal_kernel, paper_radius, tolerance_radius
from engine.matrices import laplacian, stiffness_matrix, system_matrix
from engine.recursive import warm_up

__all__ = [
    "METHODS",
    "Chain",
    "ChainState",
    "TrackResult",
    "Tracker",
    "TrackerOptions",
    "deform",
    "green_kernel",
    "laplacian",
    "literal_kernel",
    "paper_radius",
    "stiffness_matrix",
    "system_matrix",
    "tolerance_radius",
    "warm_up",
]

__version__ = "0.1.0"

_LAZY = dict.fromkeys(("Tracker", "TrackResult", "TrackerOptions"), "engine.tracker")

if TYPE_CHECKING:
    from engine.tracker import Tracker, TrackerOptions, TrackResult


def __getattr__(name: str) -> object:
    """Import the tracker (and OpenCV) only when it is first used."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'engine' has no attribute {name!r}")
