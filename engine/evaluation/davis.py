"""The DAVIS measures J and F, their statistics, and the per-sequence protocol.

Definitions follow the DAVIS evaluation toolkit (``davis2017-evaluation``):

- J = |S and G| / |S or G| (intersection over union), 1 when both masks are empty;
- F = 2PR / (P + R) over boundary pixels: the one-pixel boundary maps of
  :func:`boundary_map` (Martin's ``seg2bmap``), each pixel of one matched
  when the other's boundary lies within ``ceil(0.008 * diagonal)`` pixels
  (a disk); P = 1, R = 0 when only the truth has a boundary, P = 0, R = 1
  when only the prediction has one, both 1 when neither has;
- mean, recall (share of frames above 0.5) and decay (the mean of the first
  of four bins of frames minus that of the last, the bins' ends shared as the
  toolkit's rounding makes them).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import mask_iou

BOUNDARY_TOLERANCE = 0.008
"""DAVIS's boundary tolerance: a share of the image diagonal (4 px at 480p)."""
RECALL_ABOVE = 0.5
"""A frame counts towards recall when its measure exceeds this (DAVIS)."""
DECAY_BINS = 4


def region_similarity(prediction: ArrayLike, truth: ArrayLike) -> float:
    """J: intersection over union of two masks (1.0 when both are empty)."""
    s, g = _binary(prediction), _binary(truth)
    _same_shape(s, g)
    return mask_iou(s, g)


def boundary_map(mask: ArrayLike) -> NDArray[np.bool_]:
    """One-pixel boundary of a mask, offset half a pixel towards the origin (``seg2bmap``)."""
    seg = _binary(mask)
    e = np.zeros_like(seg)
    s = np.zeros_like(seg)
    se = np.zeros_like(seg)
    e[:, :-1] = seg[:, 1:]
    s[:-1, :] = seg[1:, :]
    se[:-1, :-1] = seg[1:, 1:]
    b = (seg ^ e) | (seg ^ s) | (seg ^ se)
    b[-1, :] = seg[-1, :] ^ e[-1, :]
    b[:, -1] = seg[:, -1] ^ s[:, -1]
    b[-1, -1] = False
    return b


def boundary_measure(
    prediction: ArrayLike, truth: ArrayLike, tolerance: float = BOUNDARY_TOLERANCE
) -> float:
    """F: the boundary F-measure of DAVIS.

    Parameters
    ----------
    prediction, truth : array_like
        H x W masks, non-zero = object.
    tolerance : float
        Below 1: a share of the image diagonal, rounded up to whole pixels (DAVIS's 0.008,
        the default); from 1 on: pixels, the disk of all pixels within that distance (for
        a fraction, the DAVIS toolkit's ``skimage.morphology.disk`` makes a kernel of even
        side instead).  A reach beyond the diagonal is the diagonal: every boundary pixel
        is then near every other.

    Raises
    ------
    ValueError
        If the masks differ in shape, or ``tolerance`` is not a finite number >= 0.
    """
    if isinstance(tolerance, bool) or not isinstance(tolerance, numbers.Real):
        raise ValueError(f"tolerance must be a number; got {tolerance!r}")
    if not 0 <= tolerance < math.inf:
        raise ValueError(f"tolerance must be finite and >= 0; got {tolerance}")
    s, g = _binary(prediction), _binary(truth)
    _same_shape(s, g)
    diagonal = float(np.hypot(*s.shape))
    reach = tolerance if tolerance >= 1 else float(np.ceil(tolerance * diagonal))
    reach = min(reach, float(np.ceil(diagonal)))
    fg, gt = boundary_map(s), boundary_map(g)
    disk = _disk(reach)
    fg_near = cv2.dilate(fg.astype(np.uint8), disk) > 0
    gt_near = cv2.dilate(gt.astype(np.uint8), disk) > 0
    n_fg, n_gt = np.count_nonzero(fg), np.count_nonzero(gt)
    if n_fg == 0 and n_gt == 0:
        return 1.0
    if n_fg == 0 or n_gt == 0:
        return 0.0  # P or R is 0: F = 0
    precision = np.count_nonzero(fg & gt_near) / n_fg
    recall = np.count_nonzero(gt & fg_near) / n_gt
    if precision + recall == 0:
        return 0.0
    return float(2 * precision * recall / (precision + recall))


@dataclass(frozen=True, slots=True)
class Statistics:
    """Mean, recall and decay of one measure over a sequence's frames."""

    mean: float
    recall: float
    decay: float


def statistics(values: ArrayLike) -> Statistics:
    """DAVIS's ``db_statistics``: mean, recall (share > 0.5), decay (first bin - last bin).

    Raises
    ------
    ValueError
        No value.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        raise ValueError("statistics need at least one frame's value")
    ids = (np.round(np.linspace(1, v.size, DECAY_BINS + 1) + 1e-10) - 1).astype(np.int64)
    bins = [v[ids[i] : ids[i + 1] + 1] for i in range(DECAY_BINS)]
    return Statistics(
        float(np.mean(v)),
        float(np.mean(v > RECALL_ABOVE)),
        float(np.mean(bins[0]) - np.mean(bins[-1])),
    )


@dataclass(frozen=True, slots=True)
class SequenceScore:
    """J and F of one sequence under the DAVIS protocol.

    Attributes
    ----------
    frames : int
        Frames scored (the sequence's, first and last left out).
    j, f : Statistics
        Region similarity and boundary measure.
    j_frames, f_frames : tuple of float
        Their per-frame values.
    """

    frames: int
    j: Statistics
    f: Statistics
    j_frames: tuple[float, ...]
    f_frames: tuple[float, ...]


def score_sequence(predictions: Sequence[ArrayLike], truths: Sequence[ArrayLike]) -> SequenceScore:
    """Score a sequence's masks, its first and last frame left out (DAVIS protocol).

    Raises
    ------
    ValueError
        Different numbers of masks, fewer than 3, or masks of different sizes.
    """
    if len(predictions) != len(truths):
        raise ValueError(f"{len(predictions)} predicted masks for {len(truths)} true ones")
    if len(truths) < 3:
        raise ValueError(f"a sequence needs at least 3 frames to score (got {len(truths)})")
    pairs = list(zip(predictions[1:-1], truths[1:-1], strict=True))
    j = tuple(region_similarity(p, t) for p, t in pairs)
    f = tuple(boundary_measure(p, t) for p, t in pairs)
    return SequenceScore(len(pairs), statistics(j), statistics(f), j, f)


def _binary(mask: ArrayLike) -> NDArray[np.bool_]:
    arr = np.asarray(mask)
    if arr.ndim != 2:
        raise ValueError(f"a mask is H x W; got shape {arr.shape}")
    return np.asarray(arr != 0, dtype=np.bool_)


def _same_shape(a: NDArray[np.bool_], b: NDArray[np.bool_]) -> None:
    if a.shape != b.shape:
        raise ValueError(f"masks of different sizes: {a.shape[::-1]} and {b.shape[::-1]} (w, h)")


def _disk(radius: float) -> NDArray[np.uint8]:
    """skimage.morphology.disk(radius): the pixels within ``radius`` of the centre."""
    r = int(np.floor(radius))
    y, x = np.mgrid[-r : r + 1, -r : r + 1]
    return np.asarray((x * x + y * y) <= radius * radius, dtype=np.uint8)
