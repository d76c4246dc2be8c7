"""Image forces on contour nodes: where is the object's boundary along each normal?

Each node looks along its outward normal, ``radius`` pixels each way, at two
cues sampled with sub-pixel (bilinear) accuracy:

- region: the object probability of the appearance model; the boundary is
  the split of the profile that best separates object-like samples inside
  from background-like samples outside (an optimal 1-D step fit);
- edges: the grey-level gradient magnitude (the paper's attraction of nodes
  to the object's contour).

The result per node is a signed offset along the normal and a strength in
[0, 1]; the tracker turns them into forces for :func:`engine.deform`.
Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "BoundaryEvidence",
    "Maps",
    "boundary_pull",
    "edge_map",
    "find_boundary",
    "outward_normals",
]


@dataclass(frozen=True, slots=True)
class Maps:
    """Cue maps over a region of interest of the frame.

    Attributes
    ----------
    origin : tuple of int
        ``(x, y)`` of the region's top-left pixel in the frame.
    probability : numpy.ndarray
        float32 p(object) per pixel.
    edges : numpy.ndarray
        float32 gradient magnitude scaled to about [0, 1].
    edge_step : int
        1: ``edges`` is on the grid of ``probability``; 2: at half its
        resolution, edge pixel ``u`` covering pixels ``2u`` and ``2u + 1``
        (a ``cv2.INTER_AREA`` halving).
    """

    origin: tuple[int, int]
    probability: NDArray[np.float32]
    edges: NDArray[np.float32]
    edge_step: int = 1

    def __post_init__(self) -> None:
        if self.edge_step not in (1, 2):
            raise ValueError(f"edge_step must be 1 or 2; got {self.edge_step!r}")


@dataclass(frozen=True, slots=True)
class BoundaryEvidence:
    """Per-node boundary offsets (pixels along the outward normal) and strengths."""

    offset: NDArray[np.float64]
    strength: NDArray[np.float64]
    contrast: float


def edge_map(grey: NDArray[np.uint8], sigma: float = 1.0) -> NDArray[np.float32]:
    """Gradient magnitude of the smoothed image, divided by a robust scale.

    Computed in float32 from a contiguous copy: OpenCV's optimised 8-bit
    paths can differ in the last bit with the memory alignment of a crop,
    and tracking should be exactly repeatable.
    """
    from engine._image_kernels import scale_and_clip, sobel_magnitude

    image = np.ascontiguousarray(grey, dtype=np.float32)
    smooth = cv2.GaussianBlur(image, (0, 0), sigma) if sigma > 0 else image
    mag: NDArray[np.float32] = sobel_magnitude(np.ascontiguousarray(smooth, dtype=np.float32))
    sample = mag[::3, ::3].ravel()  # a robust 95th percentile, cheaply
    k = int(0.95 * (sample.size - 1))
    scale = float(np.partition(sample, k)[k]) if sample.size else 0.0
    scale = max(scale, 32.0)  # about 8 grey levels per pixel: weaker is noise
    scale_and_clip(mag, 1.0 / scale)
    return mag


def outward_normals(nodes: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit normals of a closed contour pointing out of its interior.

    The normal of node i is perpendicular to ``nodes[i + 1] - nodes[i - 1]``.
    In image axes (y down) a clockwise-on-screen contour has positive
    shoelace area, and (t_y, -t_x) points out of it.
    """
    from engine._image_kernels import outward_normals as normals

    result: NDArray[np.float64] = normals(np.ascontiguousarray(nodes, dtype=np.float64))
    return result


def find_boundary(
    maps: Maps,
    nodes: NDArray[np.float64],
    normals: NDArray[np.float64],
    radius: int,
    *,
    region_weight: float = 1.0,
    edge_weight: float = 0.5,
    distance_penalty: float = 0.15,
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
    from engine._image_kernels import boundary_search

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
    )
    return BoundaryEvidence(offset, strength, float(contrast))


def boundary_pull(
    maps: Maps,
    nodes: NDArray[np.float64],
    radius: int,
    *,
    region_weight: float = 1.0,
    edge_weight: float = 0.5,
    distance_penalty: float = 0.15,
) -> tuple[NDArray[np.float64], float]:
    """:func:`find_boundary` along the :func:`outward_normals`, as forces on the nodes.

    Parameters
    ----------
    maps : Maps
        Cue maps of the frame.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` nodes of a closed contour.
    radius : int
        Search distance in pixels on each side.
    region_weight, edge_weight, distance_penalty : float
        As for :func:`find_boundary`.

    Returns
    -------
    pull : numpy.ndarray
        (N, 2) ``strength * offset * normal`` per node, pixels.
    contrast : float
        The boundary evidence of :class:`BoundaryEvidence`.
    """
    from engine._image_kernels import contour_pull

    local = np.ascontiguousarray(nodes - np.asarray(maps.origin, dtype=np.float64))
    pull = np.empty_like(local)
    contrast = contour_pull(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        np.ascontiguousarray(maps.edges, dtype=np.float32),
        maps.edge_step,
        local,
        int(radius),
        float(region_weight),
        float(edge_weight),
        float(distance_penalty),
        pull,
    )
    return pull, float(contrast)
