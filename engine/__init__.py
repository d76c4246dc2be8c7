"""efdm-tracker engine: explicit physics-based deformable contour models.

Krinidis & Pitas, "2D Physics-Based Deformable Shape Models: Explicit
Governing Equations" (the equations as this project implements them:
docs/math.md).  Coordinates are ``[x, y]`` pixels (x = column, y = row), as
in OpenCV.

Three layers, as sub-packages:

- :mod:`engine.physics`: the paper's chain model and its solvers,
  :func:`deform` (equilibrium displacements under forces) and
  :class:`Chain` (static and dynamic updates); light (numpy, scipy);
- :mod:`engine.geometry`: contours, masks, normals and boxes (OpenCV);
- :mod:`engine.tracking`: :class:`Tracker` and its swappable stages.

:mod:`engine.testing` makes synthetic sequences with known ground truth,
for tests and benchmarks.  The tracking names below are imported on first
use, so that ``import engine`` loads neither OpenCV nor the compiler.
"""

from typing import TYPE_CHECKING

from engine.physics import (
    METHODS,
    Chain,
    ChainState,
    deform,
    green_kernel,
    laplacian,
    literal_kernel,
    paper_radius,
    stiffness_matrix,
    system_matrix,
    tolerance_radius,
)

__all__ = [
    "METHODS",
    "AppearanceModel",
    "BoundaryCues",
    "Chain",
    "ChainState",
    "MotionModel",
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

_LAZY = frozenset(
    ("Tracker", "TrackResult", "TrackerOptions", "AppearanceModel", "BoundaryCues", "MotionModel")
)

if TYPE_CHECKING:
    from engine.tracking import (
        AppearanceModel,
        BoundaryCues,
        MotionModel,
        Tracker,
        TrackerOptions,
        TrackResult,
    )


def warm_up() -> None:
    """Compile (or load from the on-disk cache) every compiled kernel of the engine.

    Call once at start-up in latency-sensitive programs so that the first
    deformation or tracked frame does not pay the compilation.
    """
    from engine.physics import warm_up as physics
    from engine.tracking import warm_up as tracking

    physics()
    tracking()


def __getattr__(name: str) -> object:
    """Import the tracker (and OpenCV) only when it is first used."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module("engine.tracking"), name)
    raise AttributeError(f"module 'engine' has no attribute {name!r}")
