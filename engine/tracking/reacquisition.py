"""Re-acquisition: look for a lost object by its appearance, beyond the local window.

When a frame does not end ``tracking`` (the object moved further than the
motion model could follow, was hidden, or the contour slid onto something
else), the tracker searches a window around the predicted contour that
grows with each further frame without tracking (1, 2, 4, 8 object sizes:
up to the whole frame) for the place where the remembered shape (the
contour of the last ``tracking`` frame) fits p(object) best: the
correlation of p(object) - 1/2 with a template that is +1/area inside the
shape and -1/area in a ring around it, less a mild penalty on the distance
from the prediction.  The tracker then refines and cuts there as usual and
keeps the result only if its confidence is both high
(:attr:`TrackerOptions.reacquire_above`) and clearly above the local
track's.  Coordinates are ``[x, y]`` pixels (x = column, y = row).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes, contour_to_mask, mask_iou
from engine.tracking.stages import AppearanceModel, Frame

__all__ = ["JUMP_BELOW", "MAX_REACH", "jumped", "search_reach", "search_shape"]

MAX_REACH = 8.0
"""The window grows to 8 object sizes around the prediction (a 480p frame
for most objects): doubling from 1 size, it is reached after four frames."""
RING = 3
"""Width (pixels of the search grid) of the ring the template wants background in."""
DISTANCE_PENALTY = 0.05
"""Score lost per squared object size of distance from the prediction: of
two equally good places the nearer wins; a place clearly better wins anyway."""
MIN_REACH = 16.0
"""The window reaches at least 16 pixels beyond a small object's box."""
SMALL = 40.0
"""Objects under 40 pixels across are searched at full resolution, larger ones at half."""
JUMP_BELOW = 0.7
"""A re-acquired contour whose IoU with the local one it replaces is below 0.7 jumped: it is
on probation (reported ``uncertain`` for it and the next two frames, as a jump is right
only if the object is then followed from there). One at 0.7 or more is the local contour
corrected in place, and reported as its confidence says. Of the thirty training sequences'
frames on probation (five node counts), the 81 after a re-acquisition at 0.7 or more held
71 with IoU >= 0.6 to the mask and none below 0.2; the 139 after one below 0.7 held 57 and
8. The rule held out on folds of the thirty (``python -m bench.tracking.confidence``) at
0.5 / 0.7 / 0.9: 96.1 / 96.0 / 95.8 % of the good frames ``tracking`` and 87.1 / 87.1 /
86.8 % of the bad ones not, against 95.2 and 86.8 % with every re-acquisition on probation;
0.3 flags fewer bad frames (85.2 %): half the object is not the same place. 0.7 is inside
the plateau, away from that edge."""


def jumped(local: NDArray[np.float64], found: NDArray[np.float64]) -> bool:
    """Whether the re-acquired contour ``found`` jumped from the ``local`` one it replaces.

    Parameters
    ----------
    local, found : numpy.ndarray
        (N, 2) and (M, 2) closed contours, ``[x, y]`` pixels.

    Returns
    -------
    bool
        True when the IoU of the areas they enclose (filled on a common grid of whole
        pixels, as :func:`engine.geometry.contour_to_mask` fills them) is below
        :data:`JUMP_BELOW`.

    Raises
    ------
    ValueError
        If either is not an (N, 2) array of at least 3 finite points.
    """
    local, found = as_nodes(local), as_nodes(found)
    corner = np.floor(np.minimum(local.min(axis=0), found.min(axis=0))) - 1.0
    far = np.ceil(np.maximum(local.max(axis=0), found.max(axis=0))) + 1.0
    width, height = (int(v) + 1 for v in far - corner)
    a = contour_to_mask(local - corner, (height, width))
    b = contour_to_mask(found - corner, (height, width))
    return bool(mask_iou(a, b) < JUMP_BELOW)


def search_reach(misses: int) -> float:
    """Window reach in object sizes after ``misses`` frames in a row without tracking (>= 1).

    The exponent is capped first: an object lost for a thousand frames has the widest
    window, not a float overflow.
    """
    doublings = min(max(misses, 1) - 1, math.ceil(math.log2(MAX_REACH)))
    return float(min(2.0**doublings, MAX_REACH))


def search_shape(
    image: Frame,
    predicted: NDArray[np.float64],
    shape: NDArray[np.float64],
    appearance: AppearanceModel,
    reach: float,
) -> NDArray[np.float64] | None:
    """Where ``shape`` fits the object's appearance best near ``predicted``.

    Parameters
    ----------
    image : numpy.ndarray
        The frame.
    predicted : numpy.ndarray
        (N, 2) ``[x, y]`` predicted contour: the window is centred on it.
    shape : numpy.ndarray
        (M, 2) ``[x, y]`` remembered contour; only its shape counts (it is
        moved to the prediction's centre first).
    appearance : AppearanceModel
        Gives p(object) of the window.
    reach : float
        The window reaches this many object sizes beyond the shape's box.

    Returns
    -------
    numpy.ndarray or None
        ``shape`` translated to the best place, or None when the window or
        the shape is degenerate.
    """
    height, width = image.shape[:2]
    placed = shape - shape.mean(axis=0) + predicted.mean(axis=0)
    lo, hi = placed.min(axis=0), placed.max(axis=0)
    size = float(max(hi - lo))
    margin = max(MIN_REACH, reach * size)
    x0, y0 = int(max(0, np.floor(lo[0] - margin))), int(max(0, np.floor(lo[1] - margin)))
    x1 = int(min(width, np.ceil(hi[0] + margin)))
    y1 = int(min(height, np.ceil(hi[1] + margin)))
    if x1 - x0 < 8 or y1 - y0 < 8 or size <= 0:
        return None
    f = 1.0 if size < SMALL else 0.5
    region = np.ascontiguousarray(image[y0:y1, x0:x1])
    if f != 1.0:
        region = np.asarray(
            cv2.resize(region, None, fx=f, fy=f, interpolation=cv2.INTER_AREA), np.uint8
        )
    p = appearance.probability(region) - np.float32(0.5)
    corner = np.floor(lo).astype(int) - 2 * RING - 2
    th = int(np.ceil((hi[1] - corner[1]) * f)) + RING + 2
    tw = int(np.ceil((hi[0] - corner[0]) * f)) + RING + 2
    if th > p.shape[0] or tw > p.shape[1]:
        return None
    mask = contour_to_mask((placed - corner) * f, (th, tw)) > 0
    ring = cv2.dilate(mask.astype(np.uint8), np.ones((2 * RING + 1,) * 2, np.uint8)) > 0
    ring &= ~mask
    if not mask.any() or not ring.any():
        return None
    template = np.zeros((th, tw), np.float32)
    template[mask] = 1.0 / np.count_nonzero(mask)
    template[ring] = -1.0 / np.count_nonzero(ring)
    score = cv2.matchTemplate(np.ascontiguousarray(p, np.float32), template, cv2.TM_CCORR)
    cx, cy = (corner[0] - x0) * f, (corner[1] - y0) * f
    ys, xs = np.mgrid[0 : score.shape[0], 0 : score.shape[1]]
    far = ((xs - cx) ** 2 + (ys - cy) ** 2) / max((f * size) ** 2, 1.0)
    best = np.unravel_index(int(np.argmax(score - DISTANCE_PENALTY * far)), score.shape)
    # at half resolution the template is drawn without the half pixel of cv2.resize's
    # centres (frame p is (p + 1/2) f - 1/2), so a match lands 0.5 px up and left; the
    # refinement that follows absorbs it, and corrected the thirty training sequences
    # scored 0.742 against 0.749 over five node counts (docs/tracking-log.md, 2026-11-29)
    shift = np.array([best[1] - cx, best[0] - cy], dtype=np.float64) / f
    result: NDArray[np.float64] = placed + shift
    return result
