"""Grey video described by texture: what the colour models read when there is no colour.

The appearance models (:mod:`engine.tracking.appearance`, the cut's local windows in
:mod:`engine.tracking.local_colour`) tell object from background by the histogram of
each pixel's colour.  A grey frame (an infrared or security camera, a grey video decoded
to three equal channels) leaves them one channel of 32 levels, and an object is rarely
told from its surroundings by its grey level alone: the thirty DAVIS training sequences
turned grey score J 0.556 (decay +0.324) against 0.750 in colour.

:func:`texture_image` gives such a frame two more channels that describe the texture
around each pixel, so that the same models read three: the grey level, the **edge
energy** (the gradient's magnitude averaged over a few pixels: a furry animal against
smooth water, a patterned shirt against a plain wall) and the **local contrast** (the
grey level's mean absolute deviation over a wider window).  The thirty in grey then score
0.637 / decay +0.229 over five node counts, against 0.556 / +0.324 without (``python -m
bench.tracking --cv "grey_texture=false,true" --grey --nodes 112,120,128,136,144``;
``docs/tracking-log.md``, 2026-11-29, afternoon).  The motion model and the edges still
read the grey frame itself.  Coordinates are ``[x, y]`` pixels (x = column, y = row), as
in OpenCV.
"""

from __future__ import annotations

from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CONTRAST_BOX",
    "CONTRAST_GAIN",
    "EDGE_BOX",
    "EDGE_GAIN",
    "GREY_GLANCE",
    "GREY_SAMPLE",
    "GREY_TOLERANCE",
    "is_grey",
    "texture_image",
]

EDGE_BOX: Final = 5
"""Side (half-resolution pixels) of the box the gradient's magnitude is averaged over:
about a Gaussian of 3 frame pixels, the edge energy of a pixel's neighbourhood rather than
of the pixel."""
EDGE_GAIN: Final = 0.25
"""Levels of the edge-energy channel per unit of |d/dx| + |d/dy| (3 x 3 Sobel at half
resolution, up to 2,040): a lone step of 60 grey levels, averaged over the box, reads
about 24 at the step (three bins of the colour models' 32); a fine texture of +-40
levels, an edge every pixel or two, reads 50 and more (at 0.125, 0.643 against 0.649 on
the thirty in grey at 128 nodes, a tie, with the texture's levels in fewer bins)."""
CONTRAST_BOX: Final = 7
"""Side (half-resolution pixels) of the window of the local contrast: about a Gaussian of
4 frame pixels, wider than the edge energy's, so the two channels describe the texture at
two scales."""
CONTRAST_GAIN: Final = 2.5
"""Levels of the contrast channel per grey level of mean absolute deviation from the
window's mean (about 0.8 of a standard deviation): a texture of +-20 levels reads 40."""
GREY_TOLERANCE: Final = 2
"""Largest difference (levels) between a pixel's channels for a colour frame to count as
grey: a grey source decoded to BGR, with a level of rounding."""
GREY_GLANCE: Final = 31
"""Every 31st pixel along each axis is checked first (about 430 of a 480-line frame)."""
GREY_SAMPLE: Final = 7
"""Every 7th pixel along each axis is checked (a prime, so a regular pattern of colour
cannot hide between the samples): about 2 % of the frame."""


def is_grey(image: NDArray[np.uint8]) -> bool:
    """Whether ``image`` (H x W, or H x W x 3 BGR uint8) carries no colour: one channel, or
    three equal within :data:`GREY_TOLERANCE` on every sampled pixel.

    Raises
    ------
    ValueError
        If ``image`` is not an H x W or H x W x 3 array.
    """
    if not isinstance(image, np.ndarray) or not (
        image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)
    ):
        shape = image.shape if isinstance(image, np.ndarray) else type(image)
        raise ValueError(f"is_grey takes an H x W or H x W x 3 image; got {shape}")
    if image.ndim == 2:
        return True
    # a coarse look first: a colour frame is almost always told at once (tens of
    # microseconds instead of half a millisecond for the fine grid)
    for step in (GREY_GLANCE, GREY_SAMPLE):
        sample = image[::step, ::step].astype(np.int16)
        if (sample.max(axis=2) - sample.min(axis=2)).max(initial=0) > GREY_TOLERANCE:
            return False
    return True


def texture_image(grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """H x W x 3 uint8: the grey level, the edge energy and the local contrast of ``grey``.

    The two texture channels are averages over several pixels, measured at half
    resolution in integers and drawn back up bilinearly: about 2.5 ms a 480-line frame.
    Measured in floats at full resolution with Gaussians they scored the thirty in grey a
    little higher (0.658 / +0.182 over five node counts) but cost 16 ms; the variants in
    between (box filters, half-resolution averages of a full-resolution gradient) scored
    0.642-0.648 for 5-11 ms (``docs/tracking-log.md``).

    Parameters
    ----------
    grey : numpy.ndarray
        H x W uint8 frame.

    Returns
    -------
    numpy.ndarray
        Channels (in the places of B, G, R): ``grey``; the gradient's L1 magnitude times
        :data:`EDGE_GAIN`, averaged over a box of :data:`EDGE_BOX`; the mean absolute
        deviation from the mean over a box of :data:`CONTRAST_BOX`, times
        :data:`CONTRAST_GAIN` (the boxes' sides at half resolution); each rounded and
        saturated to 0-255.

    Raises
    ------
    ValueError
        If ``grey`` is not a non-empty H x W uint8 array.
    """
    if not isinstance(grey, np.ndarray) or grey.dtype != np.uint8 or grey.ndim != 2:
        kind = f"{grey.dtype} {grey.shape}" if isinstance(grey, np.ndarray) else type(grey)
        raise ValueError(f"texture_image takes an H x W uint8 grey frame; got {kind}")
    if grey.size == 0:
        raise ValueError("texture_image takes a non-empty frame; got 0 pixels")
    h, w = grey.shape
    g = cv2.resize(grey, (max(w // 2, 1), max(h // 2, 1)), interpolation=cv2.INTER_AREA)
    gx = cv2.Sobel(g, cv2.CV_16S, 1, 0, ksize=3)
    gy = cv2.Sobel(g, cv2.CV_16S, 0, 1, ksize=3)
    slope = cv2.add(
        cv2.convertScaleAbs(gx, alpha=EDGE_GAIN), cv2.convertScaleAbs(gy, alpha=EDGE_GAIN)
    )
    edges = cv2.boxFilter(slope, cv2.CV_16U, (EDGE_BOX, EDGE_BOX), normalize=False)
    mean = cv2.boxFilter(g, -1, (CONTRAST_BOX, CONTRAST_BOX))
    deviation = cv2.boxFilter(
        cv2.absdiff(g, mean), cv2.CV_16U, (CONTRAST_BOX, CONTRAST_BOX), normalize=False
    )
    channels = [
        cv2.convertScaleAbs(edges, alpha=1.0 / EDGE_BOX**2),
        cv2.convertScaleAbs(deviation, alpha=CONTRAST_GAIN / CONTRAST_BOX**2),
    ]
    # each channel drawn up on its own: contiguous planes merge in a tenth of the time
    up = [cv2.resize(c, (w, h), interpolation=cv2.INTER_LINEAR) for c in channels]
    return np.asarray(cv2.merge([np.ascontiguousarray(grey), *up]), np.uint8)
