"""A flash: a frame far brighter or darker than the last one tracked, passed over.

A camera's flash, a strobe, lightning or an exposure glitch washes one frame or two out:
the colours the models learnt are gone from it, and the contour tracked into it loses
what no longer shows (on the validation five with one frame at half the sequence washed
out to 0.3 x frame + 190 grey levels, blackswan's contour lost the neck, IoU 0.32, and took
about 13 frames to grow it back; J 0.724 against 0.770 without the flash).  The tracker
passes such a frame over instead: it reports the last contour, ``uncertain`` (or
``lost`` if it was), learns nothing, and tracks the next frame from the last one it
tracked (the same clips: 0.753).  At most :data:`FLASH_FRAMES` in a row are passed over,
so that a light switched on, which stays, is followed from the frame after.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["FLASH_FRAMES", "FLASH_RATIO", "flashed"]

FLASH_RATIO: Final = 1.5
"""A frame whose mean grey level (plus one) is this many times the last tracked frame's,
or that one's this many times its own, is a flash: the lighting stage follows changes of
a few percent a frame (:mod:`engine.tracking.lighting`); from one frame to the next the
thirty-five DAVIS sequences change by at most 1.31 times (bmx-bumps, a rider passing
before the camera; the others 1.09) and the generated clips of seeds 0-23 by 1.04."""
FLASH_FRAMES: Final = 2
"""Most frames in a row passed over: a flash lasts a frame or two; what lasts longer is a
new light, to be followed."""


def flashed(grey: NDArray[np.uint8], previous: NDArray[np.uint8], passed: int) -> bool:
    """Whether ``grey`` is a flash after ``previous`` (the last frame tracked), with
    ``passed`` frames passed over since it.

    Parameters
    ----------
    grey, previous : numpy.ndarray
        H x W uint8 grey frames.
    passed : int
        Frames in a row passed over before ``grey``: at :data:`FLASH_FRAMES` none is.
    """
    if passed >= FLASH_FRAMES:
        return False
    level = float(cv2.mean(grey)[0]) + 1.0
    before = float(cv2.mean(previous)[0]) + 1.0
    return max(level / before, before / level) > FLASH_RATIO
