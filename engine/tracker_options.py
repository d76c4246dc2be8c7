"""``TrackerOptions``: the tuning of :class:`engine.tracker.Tracker` and its bounds.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV;
distances below are in pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from engine._validation import as_stiffness

__all__ = ["TrackerOptions"]

_INTEGER_BOUNDS = {"search_radius": 256, "iterations": 100, "band": 256, "max_features": 1000}
_NUMBER_BOUNDS: dict[str, float] = {
    "tolerance": math.inf,
    "region_weight": math.inf,
    "edge_weight": math.inf,
    "distance_penalty": math.inf,
    "flow_stiffness": 1e6,
    "learning_rate": 1.0,
}


@dataclass(frozen=True, slots=True)
class TrackerOptions:
    """Tuning of :class:`engine.tracker.Tracker`; the defaults are meant to be good.

    Attributes
    ----------
    stiffness : float
        ``a = k/m`` of the chain that regularises the image forces.
    search_radius : int
        How far (pixels, 1-256) each node looks for the boundary on the
        first iteration; later iterations look less far.
    iterations : int
        Most refinement iterations per frame (1-100).
    tolerance : float
        Converged when no node moved more than this (pixels) in an iteration.
    region_weight, edge_weight, distance_penalty : float
        Cue weights of :func:`engine.image_forces.find_boundary`.
    band : int
        Width (pixels, 1-256) of the background ring of the colour model.
    learning_rate : float
        Share in [0, 1] of each confident frame blended into the colour model.
    max_features : int
        Corners tracked inside the object for the motion prediction (1-1000).
    flow_stiffness : float
        ``a`` of the chain that smooths the per-node optical flow added to
        the similarity prediction (0 disables the non-rigid prediction).
    occlusion : bool
        Treat pixels that were the object's and now look like background,
        inside the rigidly moved silhouette, as covered by an occluder.

    Raises
    ------
    ValueError
        If a field is of the wrong type or outside its bounds.
    """

    stiffness: float = 40.0
    search_radius: int = 12
    iterations: int = 10
    tolerance: float = 0.25
    region_weight: float = 1.0
    edge_weight: float = 0.5
    distance_penalty: float = 0.15
    band: int = 15
    learning_rate: float = 0.05
    max_features: int = 40
    flow_stiffness: float = 20.0
    occlusion: bool = True

    def __post_init__(self) -> None:
        as_stiffness(self.stiffness)
        for name, top in _INTEGER_BOUNDS.items():
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
                raise ValueError(f"{name} must be an integer in [1, {top}]; got {value!r}")
        for name, limit in _NUMBER_BOUNDS.items():
            value = getattr(self, name)
            ok = isinstance(value, int | float) and not isinstance(value, bool)
            if not ok or not math.isfinite(value) or not 0 <= value <= limit:
                raise ValueError(f"{name} must be a finite number in [0, {limit:g}]; got {value!r}")
        if not isinstance(self.occlusion, bool):
            raise ValueError(f"occlusion must be true or false; got {self.occlusion!r}")
