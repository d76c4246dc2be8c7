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
read the grey frame itself.

A monochrome frame need not have three equal channels: a sepia tone, an infrared
camera's cast or a codec's chroma noise make each channel an affine function of the grey
level instead (:func:`is_tinted`).  Read as colour, the thirty in a sepia tone through
YUV 4:2:0 scored 0.595 (decay +0.293) at 128 nodes; read as grey, with their texture,
0.637 / +0.246, against 0.644 for the same frames in plain grey (``python -m
bench.tracking --cv "grey_texture=true" --sets davis-train --nodes 128 --tint``, and
``--grey``).  Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import math
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
    "TINT_GLANCE",
    "TINT_KEPT",
    "TINT_SLOPE",
    "TINT_TOLERANCE",
    "is_grey",
    "is_tinted",
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
TINT_TOLERANCE: Final = 6.0
"""Largest difference (levels) of a channel from an affine function of the grey level, at
a quarter of the resolution, for a frame whose channels differ to count as grey.  On
monochrome DAVIS frames given a sepia tone (channels 0.80 g + 8, 0.92 g + 6, g + 4) or an
infrared camera's magenta cast, raw, through YUV 4:2:0 or JPEG at quality 75: at most 5.0
(sepia at quality 75; 3.5 through YUV 4:2:0 alone); with chroma noise of +-1 through YUV
4:2:0: 1.7.  A colour difference of a few levels is still colour: the generated
``matched_background`` (the object's grey beside it, B +8 and R -3 off) reads 10.6 and
more on the first frame of seeds 0-23, every other generated condition but
``low_contrast`` (one channel's levels, 1.5-2.4) 13.1 and more, and the least coloured
DAVIS frame (every third of the thirty-five sequences') 22.3 (``dog``).  Read as colour,
the thirty in grey with a sepia tone or a cast scored J 0.555 and 0.584 at 128 nodes,
against 0.643 in grey."""
TINT_SLOPE: Final = 0.25
"""Most a channel's slope against the grey level (their mean is 1) may differ from 1 for a
frame to count as tinted: a tint changes the channels nearly alike (the sepia tone above
0.89 / 1.02 / 1.09, the cast 1.02 / 0.95 / 1.02), while two flat colours lie exactly on a
line in any case (orange on dark blue: -0.78 / 1.30 / 2.48), and their colours are the
cue."""
TINT_KEPT: Final = 12.0
"""The same difference up to which a frame is still read as grey on a track in grey: a
codec smears a tint's colour further on some frames (sepia through JPEG at quality 30:
11.6) than it did on the first, and a track's look should not flip with them."""
TINT_GLANCE: Final = 24.0
"""The same difference at full resolution on the glance's pixels (:data:`GREY_GLANCE`),
above which a frame is colour without a closer look (twice :data:`TINT_KEPT`): the tinted
frames above reach 19.7 there (a codec's colour edges), while 98.8 % of the DAVIS frames
exceed 24 (the rest cost the closer look, about 1 ms)."""
TINT_HALVINGS: Final = 2
"""Halvings (:func:`cv2.pyrDown`) before the closer look: a quarter of the resolution, where
a codec's half-resolution colour no longer shows at the grey level's edges."""
TINT_SAMPLE: Final = 2
"""Every other pixel of the quarter resolution is read: a 20-pixel coloured object
still gives about six."""


def is_grey(image: NDArray[np.uint8]) -> bool:
    """Whether ``image`` (H x W, or H x W x 3 BGR uint8) carries no colour: one channel, or
    three equal within :data:`GREY_TOLERANCE` on every sampled pixel.

    Raises
    ------
    ValueError
        If ``image`` is not an H x W or H x W x 3 array.
    """
    from engine.tracking._label_kernels import colour_spread

    _check(image, "is_grey")
    if image.ndim == 2:
        return True
    # a coarse look first: a colour frame is almost always told at once, at its first
    # coloured pixel (microseconds instead of half a millisecond for the fine grid)
    pixels = np.asarray(image, np.uint8)
    return not any(
        colour_spread(pixels, step, GREY_TOLERANCE) for step in (GREY_GLANCE, GREY_SAMPLE)
    )


def is_tinted(image: NDArray[np.uint8], tolerance: float = TINT_TOLERANCE) -> bool:
    """Whether ``image`` (H x W, or H x W x 3 BGR uint8) is one channel's levels: grey
    (:func:`is_grey`), or three channels each an affine function of the grey level
    within ``tolerance`` levels (a monochrome frame with a tint: sepia, an infrared
    camera's cast, the chroma noise a codec adds to a grey frame; :data:`TINT_TOLERANCE`,
    and :data:`TINT_KEPT` for a track already in grey).

    Such a frame's colours say nothing its grey level does not.  Judged at a quarter of
    the resolution: a codec's colour, at half the resolution and in blocks, smears a
    tint across the grey level's edges, and averaging cancels that (a glance at the full
    resolution first, within :data:`TINT_GLANCE`, turns away a colour frame).  A colour
    scene can show one channel's levels too (an object hidden, a generated clip's grey
    background): the tracker reads a tinted frame as grey only on a track's first frame
    and while it tracks in grey (:class:`engine.tracking.Tracker`).

    Raises
    ------
    ValueError
        If ``image`` is not an H x W or H x W x 3 array, or ``tolerance`` is not a
        finite number of levels >= 0.
    """
    _check(image, "is_tinted")
    if isinstance(tolerance, bool) or not (
        isinstance(tolerance, int | float) and 0 <= tolerance < math.inf
    ):
        raise ValueError(f"tolerance must be a finite number of levels >= 0; got {tolerance!r}")
    if is_grey(image):
        return True
    if _affine_fit(image[::GREY_GLANCE, ::GREY_GLANCE])[0] > TINT_GLANCE:
        return False
    small = image
    for _ in range(TINT_HALVINGS):
        if min(small.shape[:2]) >= 2:
            small = np.asarray(cv2.pyrDown(small), np.uint8)
    residual, slopes = _affine_fit(small[::TINT_SAMPLE, ::TINT_SAMPLE])
    # one channel's levels, and a tint's: each channel rises with the grey level nearly
    # as the others do (two flat colours, orange on blue, also lie on a line)
    return residual <= tolerance and float(np.abs(slopes - 1.0).max()) <= TINT_SLOPE


def _check(image: NDArray[np.uint8], name: str) -> None:
    """ValueError unless ``image`` is an H x W or H x W x 3 array."""
    if not isinstance(image, np.ndarray) or not (
        image.ndim == 2 or (image.ndim == 3 and image.shape[2] == 3)
    ):
        shape = image.shape if isinstance(image, np.ndarray) else type(image)
        raise ValueError(f"{name} takes an H x W or H x W x 3 image; got {shape}")


def _affine_fit(sample: NDArray[np.uint8]) -> tuple[float, NDArray[np.float32]]:
    """The largest difference (levels) of a sampled pixel's channels from their
    least-squares affine functions of its mean level, and the (3,) slopes of those
    functions (their mean is 1; all 0 for a flat sample)."""
    pixels = sample.reshape(-1, 3).astype(np.float32)
    if len(pixels) < 2:
        return 0.0, np.ones(3, np.float32)
    level = pixels.mean(axis=1)
    level -= level.mean()
    centred = pixels - pixels.mean(axis=0)
    spread = float(level @ level)
    slopes = level @ centred / spread if spread > 0 else np.zeros(3, np.float32)
    return float(np.abs(centred - np.outer(level, slopes)).max()), slopes


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
