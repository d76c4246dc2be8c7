"""Motion prediction between frames: pyramidal Lucas-Kanade, forward-backward
checked, and a robust similarity fit (OpenCV).

Coordinates are ``[x, y]`` pixels (x = column, y = row).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask

__all__ = ["Motion", "estimate_motion"]


@dataclass(frozen=True, slots=True)
class Motion:
    """A 2 x 3 similarity transform and how well the points supported it.

    Attributes
    ----------
    matrix : numpy.ndarray
        2 x 3 float64, maps ``[x, y, 1]`` of the previous frame to the current one.
    inlier_ratio : float
        Share of the tracked points that passed the forward-backward check
        and agreed with the fit, in [0, 1].
    points : int
        How many points were tracked.
    """

    matrix: NDArray[np.float64]
    inlier_ratio: float
    points: int

    def apply(self, nodes: NDArray[np.float64]) -> NDArray[np.float64]:
        """Transform ``[x, y]`` nodes."""
        result: NDArray[np.float64] = nodes @ self.matrix[:, :2].T + self.matrix[:, 2]
        return result

    @staticmethod
    def identity(points: int = 0) -> Motion:
        """No motion, no support."""
        return Motion(np.hstack([np.eye(2), np.zeros((2, 1))]), 0.0, points)


def _features(
    grey: NDArray[np.uint8], nodes: NDArray[np.float64], max_features: int
) -> NDArray[np.float32]:
    """Corners inside (and just around) the contour, plus every fourth contour node."""
    x0, y0, x1, y1 = _window(grey.shape, nodes, 8)
    sub = np.ascontiguousarray(grey[y0:y1, x0:x1])
    local = nodes - [x0, y0]
    mask = np.asarray(
        cv2.dilate(contour_to_mask(local, sub.shape), np.ones((7, 7), np.uint8)), np.uint8
    )
    corners = cv2.goodFeaturesToTrack(
        sub, maxCorners=max_features, qualityLevel=0.01, minDistance=5, mask=mask, blockSize=5
    )
    pts = nodes[::4].astype(np.float32)
    if corners is not None:
        pts = np.vstack(
            [pts, np.asarray(corners, np.float32).reshape(-1, 2) + np.array([x0, y0], np.float32)]
        )
    return pts


def _window(
    shape: tuple[int, ...], nodes: NDArray[np.float64], margin: int
) -> tuple[int, int, int, int]:
    """Bounding box of the nodes grown by ``margin``, clipped to the frame."""
    h, w = shape[:2]
    x0, y0 = np.floor(nodes.min(axis=0)).astype(int) - margin
    x1, y1 = np.ceil(nodes.max(axis=0)).astype(int) + margin + 1
    x0, y0 = min(max(int(x0), 0), w - 1), min(max(int(y0), 0), h - 1)
    return x0, y0, max(min(int(x1), w), x0 + 1), max(min(int(y1), h), y0 + 1)


def estimate_motion(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    *,
    max_features: int = 80,
    window: int = 15,
    levels: int = 3,
    fb_threshold: float = 1.0,
    ransac_threshold: float = 2.0,
) -> Motion:
    """Similarity motion of the object between two grey frames.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    nodes : numpy.ndarray
        The contour in ``previous``, (N, 2) ``[x, y]``.
    max_features : int
        Corners sought inside the contour (besides the nodes themselves).
    window, levels : int
        Lucas-Kanade window side and pyramid levels.
    fb_threshold : float
        Largest forward-backward error (pixels) of a kept point.
    ransac_threshold : float
        RANSAC reprojection threshold (pixels).

    Returns
    -------
    Motion
        Identity with zero support when too few points survive.
    """
    # Work on the object's surroundings only: 64 pixels of context cover any
    # plausible motion between frames (the pyramid reaches window * 2^levels).
    x0, y0, x1, y1 = _window(previous.shape, nodes, min(64, window * (1 << levels)))
    previous, current = previous[y0:y1, x0:x1], current[y0:y1, x0:x1]
    origin = np.array([x0, y0], dtype=np.float64)
    pts = _features(previous, nodes - origin, max_features)
    h, w = previous.shape
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < w) & (pts[:, 1] >= 0) & (pts[:, 1] < h)
    pts = pts[inside]
    if len(pts) < 3:
        return Motion.identity(len(pts))
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 10, 0.03)

    size = (window, window)

    def flow(
        a: NDArray[np.uint8], b: NDArray[np.uint8], p: NDArray[np.float32]
    ) -> tuple[NDArray[np.float32], NDArray[np.uint8]]:
        moved, status, _ = cv2.calcOpticalFlowPyrLK(
            a, b, p, p.copy(), winSize=size, maxLevel=levels, criteria=criteria
        )
        return np.asarray(moved, np.float32).reshape(-1, 2), np.asarray(status, np.uint8)

    fwd, st1 = flow(previous, current, pts)
    back, st2 = flow(current, previous, fwd)
    fb = np.linalg.norm(back - pts, axis=1)
    good = (st1.ravel() == 1) & (st2.ravel() == 1) & (fb < fb_threshold)
    if good.sum() < 3:
        return Motion.identity(len(pts))
    src, dst = pts[good], fwd[good]
    matrix, inliers = cv2.estimateAffinePartial2D(
        src, dst, method=cv2.RANSAC, ransacReprojThreshold=ransac_threshold, maxIters=500
    )
    if matrix is None or not np.isfinite(matrix).all():
        shift = np.median(dst - src, axis=0)
        matrix = np.array([[1.0, 0.0, shift[0]], [0.0, 1.0, shift[1]]])
        support = float(good.mean()) * 0.5
    else:
        support = float(inliers.sum()) / len(pts)
    matrix = np.asarray(matrix, dtype=np.float64)
    # back to frame coordinates: T(o) M T(-o)
    matrix[:, 2] += origin - matrix[:, :2] @ origin
    return Motion(matrix, support, len(pts))


@dataclass(frozen=True, slots=True)
class FlowField:
    """Dense optical flow around a contour, computed at half resolution.

    Attributes
    ----------
    origin : tuple of int
        ``(x, y)`` of the crop's top-left pixel in the frame.
    flow : numpy.ndarray
        (h, w, 2) float32 displacement of the half-resolution crop, in
        half-resolution pixels.
    """

    origin: tuple[int, int]
    flow: NDArray[np.float32]

    def at(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Displacement (frame pixels) at ``[x, y]`` frame points, bilinear."""
        where = (0.5 * (points - self.origin)).astype(np.float32).reshape(-1, 1, 2)
        sampled = [
            cv2.remap(
                np.ascontiguousarray(self.flow[..., k]),
                where[..., 0],
                where[..., 1],
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REPLICATE,
            ).reshape(-1)
            for k in (0, 1)
        ]
        result = 2.0 * np.stack(sampled, axis=1).astype(np.float64)
        return np.where(np.isfinite(result), result, 0.0)


def dense_flow(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    *,
    margin: int = 48,
) -> FlowField | None:
    """OpenCV DIS optical flow (ultrafast preset) on the contour's surroundings.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` contour in ``previous``.
    margin : int
        Context kept around the contour (pixels).

    Returns
    -------
    FlowField or None
        None when the crop is empty.
    """
    x0, y0, x1, y1 = _window(previous.shape, nodes, margin)
    a = np.ascontiguousarray(previous[y0:y1, x0:x1])
    b = np.ascontiguousarray(current[y0:y1, x0:x1])
    if min(a.shape) < 2:
        return None
    # Half resolution is plenty for a flow that the chain smooths anyway.  DIS
    # needs at least 32 x 32 pixels (smaller or very flat inputs crash it):
    # pad by replication and crop the flow back.
    half_a = cv2.resize(a, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    half_b = cv2.resize(b, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
    h, w = half_a.shape
    pad_y, pad_x = max(0, 32 - h), max(0, 32 - w)
    if pad_y or pad_x:
        half_a = cv2.copyMakeBorder(half_a, 0, pad_y, 0, pad_x, cv2.BORDER_REPLICATE)
        half_b = cv2.copyMakeBorder(half_b, 0, pad_y, 0, pad_x, cv2.BORDER_REPLICATE)
    dis = cv2.DISOpticalFlow.create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    flow = np.asarray(
        dis.calc(half_a, half_b, np.zeros((*half_a.shape, 2), np.float32)), dtype=np.float32
    )[:h, :w]
    return FlowField((x0, y0), np.ascontiguousarray(flow))


def node_flow(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    inward: NDArray[np.float64],
    *,
    depth: float = 3.0,
    margin: int = 48,
) -> NDArray[np.float64]:
    """Dense optical flow (:func:`dense_flow`) read ``depth`` pixels inside each node.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` contour in ``previous``.
    inward : numpy.ndarray
        (N, 2) unit vectors into the object.
    depth : float
        Sampling depth inside the object (pixels).
    margin : int
        Context kept around the contour for the flow computation (pixels).

    Returns
    -------
    numpy.ndarray
        (N, 2) displacement of each node from ``previous`` to ``current``.
    """
    field = dense_flow(previous, current, nodes, margin=margin)
    if field is None:
        return np.zeros_like(nodes)
    return field.at(nodes + depth * inward)
