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

from engine.geometry import polygon_area

__all__ = ["BoundaryEvidence", "Maps", "edge_map", "find_boundary", "outward_normals"]


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
    """

    origin: tuple[int, int]
    probability: NDArray[np.float32]
    edges: NDArray[np.float32]


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
    image = np.ascontiguousarray(grey, dtype=np.float32)
    smooth = cv2.GaussianBlur(image, (0, 0), sigma) if sigma > 0 else image
    gx = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.asarray(cv2.magnitude(gx, gy), dtype=np.float32)
    sample = mag[::3, ::3].ravel()  # a robust 95th percentile, cheaply
    k = int(0.95 * (sample.size - 1))
    scale = float(np.partition(sample, k)[k]) if sample.size else 0.0
    scale = max(scale, 32.0)  # about 8 grey levels per pixel: weaker is noise
    return np.asarray(np.minimum(mag / scale, 1.0), dtype=np.float32)


def outward_normals(nodes: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit normals of a closed contour pointing out of its interior."""
    tangent = np.empty_like(nodes)
    tangent[1:-1] = nodes[2:] - nodes[:-2]
    tangent[0] = nodes[1] - nodes[-1]
    tangent[-1] = nodes[0] - nodes[-2]
    length = np.hypot(tangent[:, 0], tangent[:, 1])
    tangent = tangent / np.maximum(length, 1e-9)[:, None]
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    # In image axes (y down) a clockwise-on-screen contour has positive shoelace
    # area, and (t_y, -t_x) points out of it.
    result: NDArray[np.float64] = normal if polygon_area(nodes) >= 0 else -normal
    return result


def _sample(image: NDArray[np.float32], points: NDArray[np.float64]) -> NDArray[np.float32]:
    """Bilinear samples at (N, K, 2) ``[x, y]`` points, as an (N, K) map.

    OpenCV's remap takes maps of at most 32767 rows and columns, so a
    profile per row keeps any number of nodes and samples within reach.
    """
    n, k = points.shape[:2]
    values = np.empty((n, k), dtype=np.float32)
    for start in range(0, n, 32767):
        chunk = points[start : start + 32767].astype(np.float32)
        values[start : start + 32767] = cv2.remap(
            image,
            np.ascontiguousarray(chunk[..., 0]),
            np.ascontiguousarray(chunk[..., 1]),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
    return values


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
    steps = np.arange(-radius, radius + 1, dtype=np.float64)
    local = nodes - np.asarray(maps.origin, dtype=np.float64)
    points = local[:, None, :] + steps[None, :, None] * normals[:, None, :]
    prob = _sample(maps.probability, points).astype(np.float64)
    edge = _sample(maps.edges, points).astype(np.float64)
    # split between sample j and j + 1: object-like before, background-like after
    q = prob - 0.5
    before = np.cumsum(q, axis=1)[:, :-1]
    total = before[:, -1:] + q[:, -1:]
    region = (2.0 * before - total) / (len(steps) / 2.0)
    edges = 0.5 * (edge[:, :-1] + edge[:, 1:])
    position = 0.5 * (steps[:-1] + steps[1:])
    score = (
        region_weight * region
        + edge_weight * edges
        - distance_penalty * np.abs(position)[None, :] / max(radius, 1)
    )
    best = np.argmax(score, axis=1)
    rows = np.arange(len(nodes))
    strength = np.clip(score[rows, best], 0.0, 1.0)
    inside = prob[:, : radius + 1].mean(axis=1)
    outside = prob[:, radius:].mean(axis=1)
    return BoundaryEvidence(position[best], strength, float(np.mean(inside - outside)))
