"""Where is the object's boundary along each node's normal?

Each node looks along its outward normal, ``radius`` pixels each way, at two
cues of :class:`engine.tracking.maps.Maps` sampled with sub-pixel (bilinear)
accuracy:

- region: the object probability of the appearance model; the boundary is
  the split of the profile that best separates object-like samples inside
  from background-like samples outside (an optimal 1-D step fit);
- edges: the grey-level gradient magnitude (the paper's attraction of nodes
  to the object's contour).

The result per node is a signed offset along the normal and a strength in
[0, 1].  :func:`find_boundary` is the inspectable Python face of the compiled
search that :func:`engine.tracking.refine` runs inside its iteration loop
(the same kernel), for diagnostics and tests.  Coordinates are ``[x, y]``
pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.tracking.maps import Maps
from engine.tracking.options import TrackerOptions

__all__ = ["BoundaryEvidence", "find_boundary"]

_DEFAULTS = TrackerOptions()


@dataclass(frozen=True, slots=True)
class BoundaryEvidence:
    """Per-node boundary offsets (pixels along the outward normal) and strengths."""

    offset: NDArray[np.float64]
    strength: NDArray[np.float64]
    contrast: float


def find_boundary(
    maps: Maps,
    nodes: NDArray[np.float64],
    normals: NDArray[np.float64],
    radius: int,
    *,
    region_weight: float = _DEFAULTS.region_weight,
    edge_weight: float = _DEFAULTS.edge_weight,
    distance_penalty: float = _DEFAULTS.distance_penalty,
) -> BoundaryEvidence:
    """Most likely boundary position along each node's normal.

    Parameters
    ----------
    maps : Maps
        Cue maps of the frame.
    nodes, normals : numpy.ndarray
        (N, 2) ``[x, y]`` nodes and their outward unit normals.
    radius : int
        Search distance in pixels on each side.
    region_weight, edge_weight : float
        Weights of the region step score and of the edge strength.
    distance_penalty : float
        Score lost per ``radius`` of displacement (prefers small moves).

    Returns
    -------
    BoundaryEvidence
        Offsets in pixels (positive = outward) and strengths in [0, 1].
    """
    from engine.tracking._image_kernels import boundary_search

    local = np.ascontiguousarray(nodes - np.asarray(maps.origin, dtype=np.float64))
    offset = np.empty(len(nodes))
    strength = np.empty(len(nodes))
    contrast = boundary_search(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        np.ascontiguousarray(maps.edges, dtype=np.float32),
        maps.edge_step,
        local,
        np.ascontiguousarray(normals, dtype=np.float64),
        int(radius),
        float(region_weight),
        float(edge_weight),
        float(distance_penalty),
        offset,
        strength,
        np.zeros(len(nodes)),
    )
    return BoundaryEvidence(offset, strength, float(contrast))
