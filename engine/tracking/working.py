"""The working resolution: frames larger than the tracker was tuned for are tracked downscaled.

The tracker's constants are in pixels of 480-line video, the resolution of the DAVIS
sequences it was tuned and cross-validated on: the cue maps' search radius, the cut's
band, the Lucas-Kanade windows and pyramid, the motion contrast's averaging window,
the context kept around the contour.  On larger frames of the same scene each of these
covers less of the object, and a frame costs more.  The thirty training sequences drawn
at 720 lines (x 1.5) and tracked as they are score J 0.722 (0.754 at 480 lines), at 1080
lines 0.679 (decay +0.201), and a frame takes 1.7 and 2.6 times as long; tracked at the
working resolution, 0.748 and 0.748 (decay +0.097), at about 1.1 and 1.2 times a
480-line frame's time (``python -m bench.tracking --cv "working_side=0,480" --resize
1.5``; ``docs/tracking-log.md``, 2026-11-29, afternoon).

:func:`working_scale` decides: a frame whose shorter side exceeds
:attr:`~engine.tracking.options.TrackerOptions.working_side` is brought down to it
(the aspect ratio kept, each side rounded to whole pixels), and :class:`WorkingScale`
converts frames, masks and ``[x, y]`` points between the frame and the working grid.
Pixel centres correspond as :func:`cv2.resize` maps them: frame ``p`` is working
``(p + 1/2) f - 1/2``, ``f`` the side's factor.  Coordinates are ``[x, y]`` pixels
(x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import polygon_area
from engine.tracking._frames import as_frame, repeatable_opencv
from engine.tracking.noise import Smoothing

__all__ = [
    "MIN_GRID_SIDE",
    "WORKING_SIDE",
    "WorkingFrames",
    "WorkingScale",
    "downscale",
    "object_grid_side",
    "working_scale",
]

Grid = tuple[NDArray[np.uint8], NDArray[np.uint8], Smoothing]
"""A frame on a working grid: its image (BGR or grey), its grey, and its smoothing."""

WORKING_SIDE = 480
"""Default shorter side (pixels) of the frames tracked: the DAVIS sequences' 480 lines,
on which every pixel constant of the tracker was chosen.  Frames of 480 lines or fewer
are tracked as they are (bit for bit as without the working resolution)."""
MIN_GRID_SIDE = 64
"""The fewest lines a large object's grid (:func:`object_grid_side`) is brought down to:
the smallest ``working_side`` allowed.  It binds only for an object nearly as large as a
frame of an extreme aspect ratio (the square root of an area is at most the geometric
mean of the frame's sides)."""
HALF_COVERED = 0.5
"""A working pixel counts as covered (:mod:`engine.tracking.covering`) when at least
half of the frame pixels it averages are."""


def downscale(image: NDArray[np.uint8], size: tuple[int, int]) -> NDArray[np.uint8]:
    """``image`` (H x W or H x W x C uint8) brought down to ``size`` = ``(width, height)``.

    Halved by 2 x 2 means (:data:`cv2.INTER_AREA`'s exact fast path) while both sides
    stay at least twice the wanted ones, then bilinear for the last factor, which is
    then under 2: a 1080-line frame costs about 1.2 ms instead of the 11 ms of
    :data:`cv2.INTER_AREA` at a fractional factor (7 ms at 720 lines), and the thirty
    training sequences upscaled by 1.5 score the same either way (0.7444 against
    0.7345, within the noise of one track's course).  A halving drops an odd side's
    last line; the last step then samples the halved image where the frame's pixel
    centres map (:class:`WorkingScale`), so that the grid does not shrink by it.

    Raises
    ------
    ValueError
        If ``size`` is not two positive sides no larger than the image's.
    """
    width, height = size
    if not (0 < width <= image.shape[1] and 0 < height <= image.shape[0]):
        raise ValueError(
            f"size must be (width, height) within the image's {image.shape[1]} x "
            f"{image.shape[0]}; got {size}"
        )
    out, halvings, cropped = image, 0, False
    while out.shape[0] >= 2 * height and out.shape[1] >= 2 * width:
        h, w = out.shape[:2]
        cropped |= bool(h % 2 or w % 2)
        even = out[: h - h % 2, : w - w % 2]
        out = np.asarray(cv2.resize(even, (w // 2, h // 2), interpolation=cv2.INTER_AREA))
        halvings += 1
    if cropped:  # an odd side lost its last line: the scale is the image's, not what is left
        # working p is frame (p + 1/2) S / s - 1/2, and the halved pixel u is frame
        # 2^k u + (2^k - 1) / 2: so u = (p + 1/2) S / (s 2^k) - 1/2, side by side
        fx = image.shape[1] / (width * 2**halvings)
        fy = image.shape[0] / (height * 2**halvings)
        back = np.array([[fx, 0.0, 0.5 * fx - 0.5], [0.0, fy, 0.5 * fy - 0.5]])
        flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
        out = np.asarray(
            cv2.warpAffine(out, back, (width, height), flags=flags, borderMode=cv2.BORDER_REPLICATE)
        )
    elif out.shape[:2] != (height, width):
        out = np.asarray(cv2.resize(out, (width, height), interpolation=cv2.INTER_LINEAR))
    return np.ascontiguousarray(out, dtype=np.uint8)


@dataclass(frozen=True, slots=True)
class WorkingScale:
    """How a frame of ``frame_shape`` maps onto the working grid of ``size``.

    Attributes
    ----------
    frame_shape : tuple of int
        ``(height, width)`` of the frames given.
    size : tuple of int
        ``(width, height)`` of the frames tracked (as :func:`cv2.resize` takes it).
    """

    frame_shape: tuple[int, int]
    size: tuple[int, int]

    @property
    def factors(self) -> NDArray[np.float64]:
        """``[fx, fy]``: working pixels per frame pixel along x and y."""
        h, w = self.frame_shape
        return np.array([self.size[0] / w, self.size[1] / h])

    def to_working(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Frame ``[x, y]`` points on the working grid."""
        out: NDArray[np.float64] = (np.asarray(points, np.float64) + 0.5) * self.factors - 0.5
        return out

    def to_frame(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Working ``[x, y]`` points in frame pixels."""
        out: NDArray[np.float64] = (np.asarray(points, np.float64) + 0.5) / self.factors - 0.5
        return out

    def image(self, image: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """A frame (H x W or H x W x 3 uint8 of :attr:`frame_shape`) on the working grid."""
        return downscale(image, self.size)

    def mask(self, mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """An H x W bool mask on the working grid: pixels at least half covered."""
        share = cv2.resize(mask.astype(np.float32), self.size, interpolation=cv2.INTER_AREA)
        return np.asarray(share >= HALF_COVERED, np.bool_)


def object_grid_side(
    shape: tuple[int, ...], nodes: NDArray[np.float64], working_side: int, object_side: int
) -> int:
    """The shorter side of the grid a track starting on ``nodes`` is tracked on (0: the
    frames as they are), for frames of ``shape`` (``(height, width, ...)``).

    ``working_side`` as :func:`working_scale` takes it; and when the square root of the
    area the closed contour ``nodes`` (``[x, y]`` frame pixels) encloses exceeds
    ``object_side`` (0: never), the grid is as much smaller again: an object twice that
    size is tracked at half the resolution.  Its overlap is relative to its size, so a
    large object's boundary placed to a coarser pixel costs it no more than a smaller
    one's to a finer pixel, and every stage's pixels (the cue maps, the cut's band, the
    motion's crops) cost as for an object of that size.  The grid keeps at least
    :data:`MIN_GRID_SIDE` lines.
    """
    side = int(working_side)
    if object_side <= 0 or len(nodes) < 3:
        return side
    size = math.sqrt(abs(polygon_area(nodes)))
    if not size > object_side:
        return side
    shorter = min(int(shape[0]), int(shape[1]))
    wanted = max(MIN_GRID_SIDE, round(shorter * object_side / size))
    return wanted if side <= 0 else min(side, wanted)


def working_scale(shape: tuple[int, ...], side: int) -> WorkingScale | None:
    """The working grid of frames of ``shape`` (``(height, width, ...)``), or None when they
    are tracked as they are (``side`` 0, or the shorter side at most ``side``).

    Raises
    ------
    ValueError
        If ``shape`` does not start with two positive sides, or ``side`` is negative.
    """
    if len(shape) < 2 or min(int(shape[0]), int(shape[1])) < 1:
        raise ValueError(f"shape must be (height, width, ...) of positive sides; got {shape}")
    if side < 0:
        raise ValueError(f"side must be 0 (none) or positive; got {side}")
    h, w = int(shape[0]), int(shape[1])
    if side <= 0 or min(h, w) <= side:
        return None
    factor = side / min(h, w)
    size = (max(1, round(w * factor)), max(1, round(h * factor)))
    return WorkingScale((h, w), size)


class WorkingFrames:
    """One frame on the working grids of the trackers that step on it, each made once.

    Several trackers step on one frame: the objects of an
    :class:`~engine.tracking.ObjectsTracker`, the pieces of a
    :class:`~engine.tracking.PiecesTracker`.  On a frame larger than their
    ``working_side`` each would bring it down to its grid (about 1.2 ms at 1080 lines),
    convert that to grey, and smooth it if it is noisy (about 6.5 ms a 480-line grid).
    Through one ``WorkingFrames`` each grid is made once, with one
    :class:`~engine.tracking.noise.Smoothing` for all its trackers; the result is the
    same array every tracker would have made.  Safe to share between threads.

    Parameters
    ----------
    image, grey : numpy.ndarray
        The frame, as :class:`~engine.tracking.noise.Smoothing` takes it.
    """

    def __init__(self, image: NDArray[np.uint8], grey: NDArray[np.uint8]) -> None:
        self._image, self._grey = image, grey
        self._grids: dict[tuple[int, int], Grid] = {}
        self._lock = threading.Lock()

    def at(self, scale: WorkingScale, image: NDArray[np.uint8], grey: NDArray[np.uint8]) -> Grid:
        """``image`` on ``scale``'s grid, its grey and its smoothing: made once for the frame
        this was made for (the same two arrays), anew for any other."""
        if image is not self._image or grey is not self._grey:
            return _grid(scale, image)
        with self._lock:
            made = self._grids.get(scale.size)
            if made is None:
                made = self._grids[scale.size] = _grid(scale, image)
            return made


def _grid(scale: WorkingScale, image: NDArray[np.uint8]) -> Grid:
    """``image`` brought down to ``scale``'s grid, as a tracker reads it (OpenCV without IPP)."""
    with repeatable_opencv():
        small, grey = as_frame(scale.image(image))
    return small, grey, Smoothing(small, grey)
