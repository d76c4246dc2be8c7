"""How far to trust a tracked contour: a calibrated confidence and a status.

The confidence predicts the overlap (IoU) of the contour with the object. It
is a logistic model of what the frame says about the contour: how object-like
the pixels just inside it are, how object-like those just outside it are,
and whether the chain settled.  The coefficients were fitted to the overlap
on the thirty DAVIS-2016 training sequences (see :data:`COEFFICIENTS`); the
status thresholds were chosen on folds of them.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask
from engine.tracking.maps import Maps

__all__ = [
    "COEFFICIENTS",
    "LOST_BELOW",
    "TRACKING_FROM",
    "Evidence",
    "Status",
    "calibrated",
    "evidence",
    "status_of",
]

Status = Literal["tracking", "uncertain", "lost"]
"""``tracking``: the contour is on the object; ``uncertain``: it may be off;
``lost``: it most likely does not cover the object."""

INSET = 3
"""Pixels inside the contour where the object's pixels are read (a 7 x 7 erosion):
past the mixed pixels of the boundary."""
RING = 10
"""Width (pixels) of the ring outside the contour where the surroundings are read."""

COEFFICIENTS = (-2.5573, 5.1393, -2.8168, 0.7753)
"""Logistic model of the overlap: bias, mean p(object) inside, mean p(object) in
the ring outside (as the appearance model sees them, occluders included), settled
(1) or not (0).  Fitted by cross-entropy to the IoU of every scored frame of the
thirty DAVIS-2016 training sequences (tracked with the default options); on five
folds of those sequences, fitted on four and scored on the fifth, the mean
|confidence - IoU| is 0.11."""
TRACKING_FROM = 0.52
"""Confidence from which a frame is reported ``tracking``.  Chosen on the thirty
training sequences as tracked before the motion contrast (joint segmentation,
search, holding): it kept 97 % of the frames with IoU >= 0.6 ``tracking`` (goal
95 %) and reported 82 % of those with IoU < 0.2 ``uncertain`` or ``lost``; on
five folds (the threshold chosen on four, scored on the fifth: thresholds
0.515-0.575) 95.0 % and 84 %.  With the motion contrast the figures on the
thirty are 95.2 % and 92 %; on the five validation sequences only 83 % of the
good frames stay ``tracking``: the logistic model above predates the joint
segmentation and the motion contrast and wants refitting.  The tracker's own
decision to search uses :data:`engine.tracking.tracker.SEARCH_BELOW`."""
LOST_BELOW = 0.2
"""Confidence below which a frame is reported ``lost``: 0.3 % of the frames with
IoU >= 0.6 fall below it on the folds, 65 % of those with IoU < 0.2."""


@dataclass(frozen=True, slots=True)
class Evidence:
    """What a frame says about a contour.

    Attributes
    ----------
    inside : float
        Mean p(object) of the pixels :data:`INSET` pixels inside the contour.
    outside : float
        Mean p(object) in the :data:`RING`-pixel ring outside it.
    settled : bool
        Whether the refinement converged.
    """

    inside: float
    outside: float
    settled: bool


def evidence(maps: Maps, nodes: NDArray[np.float64], settled: bool) -> Evidence:
    """The :class:`Evidence` of the cue maps for the closed contour ``nodes``.

    Parameters
    ----------
    maps : Maps
        The cue maps the contour was refined on.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels.
    settled : bool
        Whether the refinement converged.

    Returns
    -------
    Evidence
        p = 0.5 (nothing known) for a part that falls outside the maps.
    """
    h, w = maps.probability.shape
    mask = contour_to_mask(nodes - np.asarray(maps.origin, dtype=np.float64), (h, w))
    inner = cv2.erode(mask, np.ones((2 * INSET + 1, 2 * INSET + 1), np.uint8)) > 0
    outer = cv2.dilate(mask, np.ones((2 * RING + 1, 2 * RING + 1), np.uint8)) > 0
    ring = outer & (mask == 0)
    p = maps.seen  # an occluder counts: the object is not seen there
    inside = float(p[inner].mean()) if inner.any() else 0.5
    outside = float(p[ring].mean()) if ring.any() else 0.5
    return Evidence(inside, outside, settled)


def calibrated(e: Evidence) -> float:
    """The confidence of :class:`Evidence`: predicted IoU, in (0, 1)."""
    bias, inside, outside, settled = COEFFICIENTS
    logit = bias + inside * e.inside + outside * e.outside + settled * float(e.settled)
    return 1.0 / (1.0 + math.exp(-logit))


def status_of(confidence: float) -> Status:
    """``tracking`` from :data:`TRACKING_FROM`, ``lost`` below :data:`LOST_BELOW`."""
    if confidence >= TRACKING_FROM:
        return "tracking"
    return "lost" if confidence < LOST_BELOW else "uncertain"
