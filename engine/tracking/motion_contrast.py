"""Motion contrast: does a pixel move with the object or with the background?

Colour alone cannot tell an object from background of its own colour; the
leading classic segmenters (ObjectFlow, BVS) also ask how each pixel moved.
Here the question is asked cheaply, by two warps of the previous frame:

1. the background's motion is a similarity fitted (RANSAC) to corners
   tracked (pyramidal Lucas-Kanade) in a ring outside the previous contour;
2. the object's is the motion model's similarity
   (:attr:`engine.tracking.stages.Prediction.matrix`);
3. each pixel of the current region is compared with the previous frame
   warped by either motion; the locally averaged absolute differences
   ``r_o`` and ``r_b`` give the log-odds

       m = GAIN * (r_b - r_o) / (r_b + r_o + NOISE)

   in ``(-GAIN, GAIN)``: positive where the object's motion explains the
   pixel better, negative where the background's does, near 0 on flat
   pixels (both warps match) and on pixels neither explains (a limb moving
   on its own).

When the two motions are alike (a still camera and a still object, or an
object carried along with the camera) the cue says nothing and is not
computed.  The log-odds are added to the colour model's (:func:`with_motion`),
handed over as odds ratios ``e^m``.  Everything is at full resolution: on
the thirty training sequences, measuring at half resolution lost most of
the gain (J 0.651 against 0.667, mean of five node counts).
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask

__all__ = ["GAIN", "motion_ratio", "with_motion"]

GAIN = 2.0
"""Largest log-odds the motion adds (a factor of e^2, about 7, on the colour
odds): enough to settle a pixel the colour models find ambiguous, not enough
to overrule clear colour evidence (compared on the thirty training sequences
with 1 and 3)."""
NOISE = 12.0
"""Grey levels added to the residuals' sum: where both warps match to within
camera noise and JPEG loss, the cue stays near 0 (compared on the thirty
training sequences with 6 and 20)."""
RING = 6
"""Background corners are sought beyond this many pixels of the previous
contour: past the boundary's mixed pixels and the contour's own error."""
MAX_CORNERS = 80
"""Background corners per frame: plenty for RANSAC, well under a millisecond."""
CORNER_QUALITY = 0.01
"""Corners down to 1 % of the strongest one's response (weakly textured
backgrounds still give some)."""
CORNER_SPACING = 3
"""Least distance (half-resolution pixels) between two corners."""
WINDOW = 9
"""Lucas-Kanade window side (pixels): 9 x 9 locks on background texture at a
quarter of the cost of 15 x 15, with no loss on the training sequences."""
LEVELS = 3
"""Pyramid levels: with :data:`WINDOW` they follow about 36 pixels of motion."""
RANSAC_THRESHOLD = 2.0
"""RANSAC inlier threshold (pixels): parallax and a wrongly tracked corner
miss the background's similarity by more."""
RANSAC_ITERATIONS = 200
"""RANSAC draws: a similarity has two points, so with half the corners
inliers 200 draws miss a clean pair with probability 0.75^200, about 1e-25."""
MIN_POINTS = 8
"""Fewest inlier corners for a background motion: fewer, and the background
is too flat to say how it moved (the cue is then off)."""
MIN_SEPARATION = 1.0
"""The two motions must move some corner of the region 1 pixel apart; closer,
a pixel's residuals cannot tell them apart."""
AVERAGE = 5
"""Side (pixels) of the box the residuals are averaged over: one pixel's
difference is noise, a 5 x 5 patch's is texture."""
MIN_SIDE = 16
"""Regions narrower or lower than this hold too little background to fit."""


def _background_motion(
    previous: NDArray[np.uint8], current: NDArray[np.uint8], nodes: NDArray[np.float64]
) -> NDArray[np.float64] | None:
    """2 x 3 similarity of the background, in region pixels, or None if not measurable."""
    h, w = previous.shape
    # corners are sought at half resolution (even sides: OpenCV's exact halving)
    half = np.asarray(
        cv2.resize(
            previous[: h - h % 2, : w - w % 2], (w // 2, h // 2), interpolation=cv2.INTER_AREA
        )
    )
    near = np.ones((RING + 1, RING + 1), np.uint8)  # RING region pixels each way
    inside = contour_to_mask((nodes - 0.5) / 2, half.shape)  # region p is half (p - 1/2) / 2
    mask = np.asarray(cv2.dilate(inside, near) == 0, np.uint8)
    corners = cv2.goodFeaturesToTrack(
        half, MAX_CORNERS, CORNER_QUALITY, CORNER_SPACING, mask=mask, blockSize=3
    )
    if corners is None or len(corners) < MIN_POINTS:
        return None
    start = np.asarray(corners * 2 + 0.5, np.float32)  # half pixel u is frame pixel 2u + 1/2
    end, found, _ = cv2.calcOpticalFlowPyrLK(
        previous, current, start, start.copy(), winSize=(WINDOW, WINDOW), maxLevel=LEVELS
    )
    kept = found.ravel() == 1
    if np.count_nonzero(kept) < MIN_POINTS:
        return None
    matrix, inliers = cv2.estimateAffinePartial2D(
        start[kept],
        end[kept],
        method=cv2.RANSAC,
        ransacReprojThreshold=RANSAC_THRESHOLD,
        maxIters=RANSAC_ITERATIONS,
    )
    if matrix is None or int(np.count_nonzero(inliers)) < MIN_POINTS:
        return None
    return np.asarray(matrix, np.float64)


def motion_ratio(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    origin: tuple[int, int],
    shape: tuple[int, int],
    nodes: NDArray[np.float64],
    motion: NDArray[np.float64],
) -> NDArray[np.float32] | None:
    """Odds ratio ``e^m`` that each pixel of a region moves with the object, not the background.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    origin, shape : tuple of int
        ``(x, y)`` of the region's top-left pixel and its ``(height, width)``
        (the cue maps' region, :func:`engine.tracking.maps.roi_box`).
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` contour in ``previous``.
    motion : numpy.ndarray
        2 x 3 similarity mapping ``[x, y, 1]`` of ``previous`` to ``current``:
        the object's motion.

    Returns
    -------
    numpy.ndarray or None
        float32 ``shape`` odds ratios ``e^m``, ``m`` the log-odds in
        ``(-GAIN, GAIN)`` (above 1: moves as the object), or None when the
        region is too small, the background's motion cannot be measured, or
        it is the object's.
    """
    x0, y0 = origin
    h, w = shape
    if min(h, w) < MIN_SIDE:
        return None
    before = np.ascontiguousarray(previous[y0 : y0 + h, x0 : x0 + w])
    after = np.ascontiguousarray(current[y0 : y0 + h, x0 : x0 + w])
    background = _background_motion(before, after, nodes - [x0, y0])
    if background is None:
        return None
    # the object's motion in region pixels: shift in, move, shift back
    obj = np.asarray(motion, np.float64).copy()
    obj[:, 2] += obj[:, :2] @ [x0, y0] - [x0, y0]
    corners = np.array([[0, 0, 1], [w, 0, 1], [0, h, 1], [w, h, 1]], np.float64)
    if np.abs(corners @ (obj - background).T).max() < MIN_SEPARATION:
        return None

    def residual(matrix: NDArray[np.float64]) -> NDArray[np.float32]:
        warped = cv2.warpAffine(
            before, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        # the box mean straight from uint8: a third of the cost of converting first
        difference = cv2.absdiff(after, warped)
        return np.asarray(cv2.boxFilter(difference, cv2.CV_32F, (AVERAGE, AVERAGE)), np.float32)

    r_o, r_b = residual(obj), residual(background)
    odds = cv2.divide(r_b - r_o, r_b + r_o + np.float32(NOISE), scale=GAIN)
    return np.asarray(cv2.exp(odds), np.float32)


def with_motion(
    probability: NDArray[np.float32], ratio: NDArray[np.float32]
) -> NDArray[np.float32]:
    """p(object) with the motion's odds ratio ``r = e^m``: ``p r / (p r + 1 - p)``."""
    from engine.tracking._image_kernels import scale_odds

    return scale_odds(
        np.ascontiguousarray(probability, np.float32), np.ascontiguousarray(ratio, np.float32)
    )
