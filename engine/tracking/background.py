"""The background's motion around a contour: a similarity fitted to corners outside it.

Two stages ask how the background moved between two frames: the motion model,
to leave out of the object's motion the corners inside the contour that moved
with the background (:func:`engine.tracking.motion.estimate_motion`), and the
motion contrast, to tell each pixel's motion (:mod:`engine.tracking.motion_contrast`).
Corners are sought at half the given resolution in a region around the contour,
beyond a ring of :data:`RING` pixels, tracked by pyramidal Lucas-Kanade at the
given resolution, and a similarity is fitted to them by RANSAC.  The motion
contrast gives frame regions; the motion model gives its crops already halved
(then every pixel here is two of the frame's, and the crop is the "frame").

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from typing import Final, Literal, TypeAlias

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, fit_similarity

__all__ = [
    "MEASURE",
    "MIN_POINTS",
    "RING",
    "Background",
    "background_motion",
    "frame_background",
    "in_region",
]

MEASURE: Final = "measure"
"""Passed for a background's motion: measure it here (around the contour)."""
Background: TypeAlias = NDArray[np.float64] | Literal["measure"] | None
"""A background's frame similarity measured elsewhere (None: not measurable there), or
:data:`MEASURE`."""
RING = 6
"""Background corners are sought beyond this many pixels of the contour: past
the boundary's mixed pixels and the contour's own error."""
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
COARSE_SPACING = 2
"""Least distance (quarter-resolution pixels) between two corners of a coarse fit
(:func:`frame_background`, ``background_motion(coarse=True)``): 8 frame pixels, about
the 6 of a fit at full resolution."""
COARSE_LEVELS = 2
"""Pyramid levels above the half-resolution images of a coarse fit: the same coarsest
level as :data:`LEVELS` above full resolution, so the same reach."""
MIN_POINTS = 8
"""Fewest inlier corners for a background motion: fewer, and the background
is too flat to say how it moved."""


def background_motion(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    origin: tuple[int, int] = (0, 0),
    *,
    coarse: bool = False,
) -> NDArray[np.float64] | None:
    """2 x 3 similarity of the background between two grey regions, or None if not measurable.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 regions of equal size, cut from two frames at ``origin``.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` frame pixels: the contour in ``previous``, whose
        inside (and :data:`RING` pixels around it) is left out.
    origin : tuple of int
        ``(x, y)`` of the regions' top-left pixel in the frame.
    coarse : bool, default False
        Seek the corners at a quarter of the regions' resolution and track them at
        half of it, as :func:`frame_background` does, instead of at half and at full:
        about 0.2 ms less a frame for the motion contrast's region (0.6 ms instead of
        0.8 ms on the validation sequences).  The contrast only asks which of two
        motions explains a pixel better; on the thirty training sequences over five
        node counts J 0.7426 against 0.7432 (``docs/tracking-log.md``).  It costs two
        generated clips of 456: ``hidden`` seed 9 (0.971 -> 0.600) and
        ``no_contrast_stretch`` seed 2 (0.953 -> 0.944), from the sparser corners.

    Returns
    -------
    numpy.ndarray or None
        float64 2 x 3 mapping frame ``[x, y, 1]`` of ``previous`` to
        ``current``; None when fewer than :data:`MIN_POINTS` corners agree
        (a flat background, or too little of it in the region).
    """
    h, w = previous.shape
    if min(h, w) < (4 if coarse else 2):
        return None
    local = np.asarray(nodes, np.float64) - np.asarray(origin, np.float64)
    side, scale, spacing, levels = RING + 1, 1, CORNER_SPACING, LEVELS  # RING pixels each way
    if coarse:  # from here on every pixel is two of the regions'
        previous, current = _halved(previous), _halved(current)
        local = (local - 0.5) / 2  # region p is half (p - 1/2) / 2
        side, scale, spacing, levels = RING // 2 + 1, 2, COARSE_SPACING, COARSE_LEVELS
    half = _halved(previous)
    inside = contour_to_mask((local - 0.5) / 2, half.shape)
    allowed = np.asarray(cv2.dilate(inside, np.ones((side, side), np.uint8)) == 0, np.uint8)
    return _fit(previous, current, half, allowed, origin, spacing, levels, scale)


def frame_background(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    excluded: NDArray[np.bool_],
    halves: tuple[NDArray[np.uint8], NDArray[np.uint8]] | None = None,
) -> NDArray[np.float64] | None:
    """The background's similarity over whole frames, the ``excluded`` pixels left out.

    For a session of several objects (:class:`engine.tracking.ObjectsTracker`):
    one fit for all of them, ``excluded`` (H x W bool) their silhouettes, grown
    by about :data:`RING` pixels.  Whole frames are a coarser question than a
    contour's surroundings, so the corners are sought at a quarter of the
    resolution and tracked at half of it (:data:`COARSE_SPACING`,
    :data:`COARSE_LEVELS`): on 640 x 480 frames 0.35 ms instead of 0.9 ms, with
    the same warp residual over ten of the training sequences (4.90 against
    4.90 grey levels).  Returns as :func:`background_motion` does.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    excluded : numpy.ndarray
        H x W bool: pixels of ``previous`` that are no background (the objects).
    halves : tuple of numpy.ndarray, optional
        ``previous`` and ``current`` already halved as :class:`FramePair`
        halves them (``cv2.INTER_AREA``), to save doing it twice.
    """
    h, w = previous.shape
    if min(h, w) < 4:
        return None
    half_previous, half_current = halves or (_halved(previous), _halved(current))
    quarter = _halved(half_previous)
    qh, qw = quarter.shape
    # a quarter pixel is excluded when any of its 4 x 4 frame pixels is, then grown by one
    block = np.ones((4, 4), np.uint8)
    flags = np.ascontiguousarray(excluded).view(np.uint8)
    hidden = cv2.dilate(flags, block, anchor=(0, 0))[: 4 * qh : 4, : 4 * qw : 4]
    grown = cv2.dilate(np.ascontiguousarray(hidden), np.ones((3, 3), np.uint8))
    allowed = np.asarray(grown == 0, np.uint8)
    # half-resolution pixel u is frame pixel 2u + 1/2
    return _fit(
        half_previous, half_current, quarter, allowed, (0, 0), COARSE_SPACING, COARSE_LEVELS, 2
    )


def _halved(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``image`` at half resolution (even sides: OpenCV's exact halving)."""
    h, w = image.shape
    return np.asarray(
        cv2.resize(image[: h - h % 2, : w - w % 2], (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    )


def _fit(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    half: NDArray[np.uint8],
    allowed: NDArray[np.uint8],
    origin: tuple[int, int],
    spacing: int = CORNER_SPACING,
    levels: int = LEVELS,
    scale: int = 1,
) -> NDArray[np.float64] | None:
    """Corners of ``half`` (``previous`` halved) where ``allowed``, tracked into ``current``,
    and the similarity RANSAC fits to them, in frame coordinates (regions at ``origin``
    whose pixel ``u`` is frame pixel ``scale * u + (scale - 1) / 2``)."""
    corners = cv2.goodFeaturesToTrack(
        half, MAX_CORNERS, CORNER_QUALITY, spacing, mask=allowed, blockSize=3
    )
    if corners is None or len(corners) < MIN_POINTS:
        return None
    start = np.asarray(corners * 2 + 0.5, np.float32)  # half pixel u is region pixel 2u + 1/2
    end, found, _ = cv2.calcOpticalFlowPyrLK(
        previous, current, start, start.copy(), winSize=(WINDOW, WINDOW), maxLevel=levels
    )
    kept = found.ravel() == 1
    if np.count_nonzero(kept) < MIN_POINTS:
        return None
    start, end = start[kept], end[kept]
    if scale != 1:
        start, end = scale * start + 0.5 * (scale - 1), scale * end + 0.5 * (scale - 1)
    matrix, inliers = fit_similarity(
        start, end, threshold=RANSAC_THRESHOLD, iterations=RANSAC_ITERATIONS
    )
    if matrix is None or int(np.count_nonzero(inliers)) < MIN_POINTS:
        return None
    fitted = np.asarray(matrix, np.float64)
    # region to frame coordinates: T(o) M T(-o)
    offset = np.asarray(origin, np.float64)
    fitted[:, 2] += offset - fitted[:, :2] @ offset
    return fitted


def in_region(matrix: NDArray[np.float64], origin: tuple[int, int]) -> NDArray[np.float64]:
    """A frame similarity in the pixels of the region at ``origin``: shift in, move, shift back."""
    local = np.asarray(matrix, np.float64).copy()
    local[:, 2] += local[:, :2] @ origin - np.asarray(origin, np.float64)
    return local
