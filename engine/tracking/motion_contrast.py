"""Motion contrast: does a pixel move with the object or with the background?

Colour alone cannot tell an object from background of its own colour; the
leading classic segmenters (ObjectFlow, BVS) also ask how each pixel moved.
Here the question is asked cheaply, by two warps of the previous frame:

1. the background's motion is a similarity fitted (RANSAC) to corners
   tracked (pyramidal Lucas-Kanade) outside the previous contour
   (:func:`engine.tracking.background.background_motion`);
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
handed over as odds ratios ``e^m``.  The residuals are at full resolution: on
the thirty training sequences, measuring them at half resolution lost most of
the gain (J 0.651 against 0.667, mean of five node counts).  The background's
similarity is fitted coarsely (``background_motion(coarse=True)``: corners at a
quarter of the resolution, tracked at half), 0.2 ms less a frame for J 0.7426
against 0.7432, and two generated clips of 456 that no longer pass.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.tracking.background import MEASURE, Background, background_motion, in_region

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
MIN_SEPARATION = 1.0
"""The two motions must move some corner of the region 1 pixel apart; closer,
a pixel's residuals cannot tell them apart."""
AVERAGE = 5
"""Side (pixels) of the box the residuals are averaged over: one pixel's
difference is noise, a 5 x 5 patch's is texture."""
MIN_SIDE = 16
"""Regions narrower or lower than this hold too little background to fit."""


def motion_ratio(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    origin: tuple[int, int],
    shape: tuple[int, int],
    nodes: NDArray[np.float64],
    motion: NDArray[np.float64],
    background: Background = MEASURE,
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
    background : numpy.ndarray, None or "measure"
        The background's frame similarity measured over the whole frame (a
        session of several objects, :mod:`engine.tracking.shared`; None: it
        could not be), or :data:`~engine.tracking.background.MEASURE` it in
        the region.

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
    if isinstance(background, str):
        background = background_motion(before, after, nodes, origin, coarse=True)
    if background is None:
        return None
    obj, background = in_region(motion, origin), in_region(background, origin)
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

    from engine.tracking._image_kernels import contrast_odds

    odds = contrast_odds(residual(obj), residual(background), NOISE, GAIN)
    return np.asarray(cv2.exp(odds), np.float32)


def with_motion(
    probability: NDArray[np.float32], ratio: NDArray[np.float32]
) -> NDArray[np.float32]:
    """p(object) with the motion's odds ratio ``r = e^m``: ``p r / (p r + 1 - p)``."""
    from engine.tracking._image_kernels import scale_odds

    return scale_odds(
        np.ascontiguousarray(probability, np.float32), np.ascontiguousarray(ratio, np.float32)
    )
