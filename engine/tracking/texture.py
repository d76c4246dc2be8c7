"""Grey video described by texture: what the colour models read when there is no colour.

The appearance models (:mod:`engine.tracking.appearance`, the cut's local windows in
:mod:`engine.tracking.local_colour`) tell object from background by the histogram of
each pixel's colour.  A grey frame (an infrared or security camera, a grey video decoded
to three equal channels) leaves them one channel of 32 levels, and an object is rarely
told from its surroundings by its grey level alone: the thirty DAVIS training sequences
turned grey score J 0.557 (decay +0.323) against 0.749 in colour.

:func:`texture_image` gives such a frame two more channels that describe the texture
around each pixel, so that the same models read three: the grey level, the **edge
energy** (the gradient's magnitude averaged over a few pixels: a furry animal against
smooth water, a patterned shirt against a plain wall) and the **local contrast** (the
grey level's standard deviation over a wider window).  The thirty in grey then score
0.665 (decay +0.144; ``docs/tracking-log.md``, 2026-11-29, afternoon).  The motion model
and the edges still read the grey frame itself.  Coordinates are ``[x, y]`` pixels
(x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CONTRAST_GAIN",
    "CONTRAST_SIGMA",
    "EDGE_SCALE",
    "EDGE_SIGMA",
    "GREY_SAMPLE",
    "GREY_TOLERANCE",
    "is_grey",
    "texture_image",
]

EDGE_SIGMA: Final = 2.0
"""Gaussian (pixels) the gradient magnitude is averaged over: the edge energy of a
pixel's neighbourhood, a few pixels across, rather than of the pixel."""
EDGE_SCALE: Final = 4.0
"""Gradient magnitude (3 x 3 Sobel, up to about 1,440 on a step of 255) per level of the
edge-energy channel: a step of 60 grey levels, a clear edge, averaged over the
neighbourhood, reads about 60 levels; strong texture saturates at 255."""
CONTRAST_SIGMA: Final = 4.0
"""Gaussian (pixels) of the window whose standard deviation is the local contrast: twice
the edge energy's, so the two channels describe the texture at two scales."""
CONTRAST_GAIN: Final = 2.0
"""Levels of the contrast channel per grey level of standard deviation: a texture of
+-20 levels reads 40; 128 and over saturate."""
GREY_TOLERANCE: Final = 2
"""Largest difference (levels) between a pixel's channels for a colour frame to count as
grey: a grey source decoded to BGR, with a level of rounding."""
GREY_SAMPLE: Final = 7
"""Every 7th pixel along each axis is checked (a prime, so a regular pattern of colour
cannot hide between the samples): about 2 % of the frame."""


def is_grey(image: NDArray[np.uint8]) -> bool:
    """Whether ``image`` (H x W, or H x W x 3 BGR uint8) carries no colour: one channel, or
    three equal within :data:`GREY_TOLERANCE` on every sampled pixel."""
    if image.ndim == 2:
        return True
    sample = image[::GREY_SAMPLE, ::GREY_SAMPLE].astype(np.int16)
    spread = sample.max(axis=2) - sample.min(axis=2)
    return bool(spread.max(initial=0) <= GREY_TOLERANCE)


def texture_image(grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """H x W x 3 uint8: the grey level, the edge energy and the local contrast of ``grey``.

    Parameters
    ----------
    grey : numpy.ndarray
        H x W uint8 frame.

    Returns
    -------
    numpy.ndarray
        Channels (in the places of B, G, R): ``grey``; the Sobel gradient magnitude
        averaged by a Gaussian of :data:`EDGE_SIGMA`, divided by :data:`EDGE_SCALE`; the
        standard deviation over a Gaussian window of :data:`CONTRAST_SIGMA` times
        :data:`CONTRAST_GAIN`; each clipped to 0-255.
    """
    g = np.asarray(grey, np.float32)
    gx = cv2.Sobel(g, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_32F, 0, 1, ksize=3)
    edges = cv2.GaussianBlur(cv2.magnitude(gx, gy), (0, 0), EDGE_SIGMA) / np.float32(EDGE_SCALE)
    mean = cv2.GaussianBlur(g, (0, 0), CONTRAST_SIGMA)
    square = cv2.GaussianBlur(g * g, (0, 0), CONTRAST_SIGMA)
    contrast = np.sqrt(np.maximum(square - mean * mean, 0.0)) * np.float32(CONTRAST_GAIN)
    out = np.empty((*grey.shape, 3), np.uint8)
    out[..., 0] = grey
    out[..., 1] = np.clip(edges, 0, 255)
    out[..., 2] = np.clip(contrast, 0, 255)
    return out
