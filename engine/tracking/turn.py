"""The object's turn between two frames: its interior's motion and its rim's normal motion.

The motion model (:func:`engine.tracking.motion.estimate_motion`) fits one
similarity to corners and to every fourth node, and on a nearly textureless
object the corners lie on its rim too.  Lucas-Kanade sees a point on an edge
move only across the edge (the aperture problem), so every rim point reports
no motion along the rim, and a turning object is fitted as turning much less
than it does: the generated ``no_contrast_stretch`` object turns by 56.6° over
39 frames, the similarities add up to 17.7°.  That is good enough for the
prediction, which the cut corrects, but the remembered outline of the shape
memory (:mod:`engine.tracking.shape_memory`) is carried by it alone where the
image says nothing, and lags the object's turn.

:func:`measure_turn` measures the rotation again for the outline: corners
sought only well inside the contour (their quality relative to the best
interior corner, so a faint shading still gives some) are tracked with the
rim's points, and a least-squares similarity is fitted in which a rim point
constrains only its motion along the contour's normal (its motion along the
rim counts at :data:`TANGENTIAL_WEIGHT`).  :func:`turned` puts that rotation
into the prediction's similarity, keeping its scale and the motion of the
contour's centroid.  Coordinates are ``[x, y]`` pixels (x = column, y = row),
as in OpenCV.
"""

from __future__ import annotations

import math
from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes, contour_to_mask, nearest, outward_normals
from engine.tracking.motion import (
    CORNER_BLOCK,
    CORNER_QUALITY,
    CORNER_SPACING,
    FB_THRESHOLD,
    LEVELS,
    LK_EPSILON,
    LK_ITERATIONS,
    NODE_STRIDE,
    WINDOW,
    FramePair,
)

__all__ = [
    "AGREE",
    "INTERIOR_CORNERS",
    "MIN_INTERIOR",
    "RIM_REACH",
    "TANGENTIAL_WEIGHT",
    "measure_turn",
    "turned",
]

INTERIOR_CORNERS: Final = 20
"""Corners sought inside the contour, at least a Lucas-Kanade half-window
(:data:`~engine.tracking.motion.WINDOW`) from its rim: half the motion model's
budget, enough for a rotation, tracked in well under a millisecond."""
RIM_REACH: Final = 9.0
"""A point within this many frame pixels of a node (half the Lucas-Kanade window
at full resolution) is on the rim: only its motion along the normal is measured."""
TANGENTIAL_WEIGHT: Final = 0.05
"""Weight of a rim point's motion along the rim: small, so that the interior
decides the rotation, but not nought, so that a rim with too few interior points
still fixes the fit.  On the generated ``no_contrast_stretch`` seed 2, measured
between its true contours frame by frame, the turns add up to 54.5° of 56.6° with 0.05
and 56.1° with 0 (17.7° for the motion model's similarities).  Not tuned."""
AGREE: Final = 4.0
"""Points that end farther than this (frame pixels) from where the prediction's
similarity takes them are left out: twice the motion model's RANSAC threshold,
room for the rotation it missed."""
MIN_INTERIOR: Final = 2
"""Fewest interior points to measure a turn: with fewer, the rim alone cannot."""
_KEEP_OFF_RIM = np.ones((WINDOW + 2, WINDOW + 2), np.uint8)
"""The square the contour's inside is eroded by before corners are sought in it."""
_SUPPORT = CORNER_BLOCK // 2 + 3
"""Pixels around the interior a corner's response reads: the block's half side, the
Sobel kernel's pixel, the local-maximum test's pixel, and one to spare."""


def measure_turn(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    matrix: NDArray[np.float64],
    *,
    frames: FramePair | None = None,
) -> float | None:
    """The object's rotation (radians) from ``previous`` to ``current``, or None.

    Parameters
    ----------
    previous, current : numpy.ndarray
        H x W ``uint8`` grey frames.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` frame pixels: the closed contour in ``previous``.
    matrix : numpy.ndarray
        2 x 3 similarity of the object from ``previous`` to ``current`` (the
        prediction's, :attr:`engine.tracking.stages.Prediction.matrix`): the
        points' first guess, and the motion they must roughly agree with.
    frames : FramePair, optional
        ``FramePair.around(previous, current, nodes)`` made already (the
        prediction's, :attr:`engine.tracking.stages.Prediction.frames`), so as
        not to crop and halve again.

    Returns
    -------
    float or None
        The angle of the fitted similarity, ``atan2`` of its rotation (positive
        turns x towards y, as ``cv2.getRotationMatrix2D`` with a negative angle);
        None when fewer than :data:`MIN_INTERIOR` interior points were tracked.

    Raises
    ------
    ValueError
        If the frames are not two grey images of one shape, ``nodes`` are not
        at least 3 finite ``[x, y]`` points, ``matrix`` is not a finite 2 x 3, or
        ``frames`` is neither a :class:`~engine.tracking.motion.FramePair` nor None.
    """
    before_full, after_full = np.asarray(previous), np.asarray(current)
    if before_full.ndim != 2 or before_full.shape != after_full.shape:
        raise ValueError("previous and current must be grey frames of one shape")
    nodes = as_nodes(nodes)
    m = np.asarray(matrix, np.float64)
    if m.shape != (2, 3) or not np.isfinite(m).all():
        raise ValueError(f"matrix must be a finite 2 x 3 similarity; got shape {m.shape}")
    frames = FramePair.given(frames, before_full, after_full, nodes)
    before, after = frames.half_previous, frames.half_current
    if min(before.shape) <= WINDOW:
        return None
    half_nodes = frames.to_half(nodes)
    # eroded by a Lucas-Kanade window and a pixel each side: no window reaches the rim
    inner = cv2.erode(contour_to_mask(half_nodes, before.shape), _KEEP_OFF_RIM)
    if not inner.any():
        return None
    corners = _interior_corners(before, np.asarray(inner, np.uint8))
    if corners is None:
        return None
    rim_points = half_nodes[::NODE_STRIDE].astype(np.float32)
    points = np.vstack([rim_points, np.asarray(corners, np.float32).reshape(-1, 2)])
    on_rim = np.arange(len(points)) < len(rim_points)
    h, w = before.shape
    inside = (points[:, 0] >= 0) & (points[:, 0] < w) & (points[:, 1] >= 0) & (points[:, 1] < h)
    points, on_rim = points[inside], on_rim[inside]
    origin = np.asarray(frames.origin, np.float64)
    # half-crop u to frame p = 2u + 1/2 + origin
    src = 2.0 * points.astype(np.float64) + 0.5 + origin
    guess = ((src @ m[:, :2].T + m[:, 2] - origin - 0.5) / 2.0).astype(np.float32)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, LK_ITERATIONS, LK_EPSILON)
    flags = cv2.OPTFLOW_USE_INITIAL_FLOW
    window = (WINDOW, WINDOW)
    fwd, ok_fwd, _ = cv2.calcOpticalFlowPyrLK(
        before,
        after,
        points,
        guess,
        winSize=window,
        maxLevel=LEVELS,
        criteria=criteria,
        flags=flags,
    )
    back, ok_back, _ = cv2.calcOpticalFlowPyrLK(
        after,
        before,
        fwd,
        points.copy(),
        winSize=window,
        maxLevel=LEVELS,
        criteria=criteria,
        flags=flags,
    )
    good = (ok_fwd.ravel() == 1) & (ok_back.ravel() == 1)
    good &= np.linalg.norm(back - points, axis=1) < 0.5 * FB_THRESHOLD  # half-res pixels
    dst = 2.0 * fwd.astype(np.float64) + 0.5 + origin
    good &= np.linalg.norm(dst - (src @ m[:, :2].T + m[:, 2]), axis=1) < AGREE
    if np.count_nonzero(good & ~on_rim) < MIN_INTERIOR:
        return None
    return _normal_fit(src[good], dst[good], on_rim[good], nodes)


def _interior_corners(
    grey: NDArray[np.uint8], inner: NDArray[np.uint8]
) -> NDArray[np.float32] | None:
    """The turn's corners: ``cv2.goodFeaturesToTrack`` of ``grey`` where ``inner`` is set.

    Sought in the box of ``inner`` grown by :data:`_SUPPORT` only (the crop's margin is
    mostly background, and about 0.1 ms a frame was spent on it): every response there
    reads the same pixels as over the whole image, so the corners are the same, in the
    same order, as those of the whole image.  ``(K, 1, 2)`` float32 ``[x, y]`` pixels of
    ``grey`` (at most :data:`INTERIOR_CORNERS`), or None when there are none.
    """
    bx, by, bw, bh = cv2.boundingRect(inner)
    x0, y0 = max(bx - _SUPPORT, 0), max(by - _SUPPORT, 0)
    x1, y1 = min(bx + bw + _SUPPORT, grey.shape[1]), min(by + bh + _SUPPORT, grey.shape[0])
    corners = cv2.goodFeaturesToTrack(
        np.ascontiguousarray(grey[y0:y1, x0:x1]),
        maxCorners=INTERIOR_CORNERS,
        qualityLevel=CORNER_QUALITY,
        minDistance=CORNER_SPACING,
        mask=np.ascontiguousarray(inner[y0:y1, x0:x1]),
        blockSize=CORNER_BLOCK,
    )
    if corners is None:
        return None
    return np.asarray(corners, np.float32) + np.array([x0, y0], np.float32)


def _normal_fit(
    src: NDArray[np.float64],
    dst: NDArray[np.float64],
    on_rim: NDArray[np.bool_],
    nodes: NDArray[np.float64],
) -> float | None:
    """The rotation of the least-squares similarity ``src -> dst`` in which rim points
    constrain their normal motion (their tangential motion at :data:`TANGENTIAL_WEIGHT`)."""
    near = nearest(src, nodes)
    rim = on_rim | (np.linalg.norm(src - nodes[near], axis=1) < RIM_REACH)
    centre = src.mean(axis=0)
    x, y = (src - centre).T
    q = dst - centre
    one, zero = np.ones_like(x), np.zeros_like(x)
    # rows of [a, b, tx, ty] for the x and the y of A p + t, A = [[a, -b], [b, a]]
    jx = np.stack([x, -y, one, zero], axis=1)
    jy = np.stack([y, x, zero, one], axis=1)
    normal = outward_normals(nodes)[near]
    tangent = np.stack([-normal[:, 1], normal[:, 0]], axis=1)
    # an interior point: its x and y; a rim point: along its normal, and weakly along the rim
    first = np.where(rim[:, None], normal, [1.0, 0.0])
    second = np.where(rim[:, None], TANGENTIAL_WEIGHT * tangent, [0.0, 1.0])
    rows = np.vstack(
        [first[:, :1] * jx + first[:, 1:] * jy, second[:, :1] * jx + second[:, 1:] * jy]
    )
    rhs = np.concatenate([np.einsum("ij,ij->i", first, q), np.einsum("ij,ij->i", second, q)])
    solution, *_ = np.linalg.lstsq(rows, rhs, rcond=None)
    a, b = float(solution[0]), float(solution[1])
    if not (math.isfinite(a) and math.isfinite(b)) or a == b == 0.0:
        return None
    return math.atan2(b, a)


def turned(
    matrix: NDArray[np.float64], nodes: NDArray[np.float64], angle: float
) -> NDArray[np.float64]:
    """``matrix`` with its rotation replaced by ``angle``, its scale and the motion of the
    centroid of ``nodes`` (``[x, y]`` frame pixels) kept."""
    m = np.asarray(matrix, np.float64)
    centre = as_nodes(nodes).mean(axis=0)
    moved = m[:, :2] @ centre + m[:, 2]
    scale = float(np.hypot(m[0, 0], m[1, 0]))
    c, s = math.cos(angle), math.sin(angle)
    linear = scale * np.array([[c, -s], [s, c]])
    result: NDArray[np.float64] = np.hstack([linear, (moved - linear @ centre)[:, None]])
    return result
