"""Sensor noise: measured on each frame, and smoothed out of what the colour models see.

A dim room, a small sensor or a high gain make every pixel's colour wander by several
levels from frame to frame.  The colour models (:mod:`engine.tracking.appearance`,
:mod:`engine.tracking.local_colour`) count colours in bins of 8 levels a channel: noise of
that size scatters the object's colours over its neighbours' bins and into the
background's, and the two are told apart less sharply.  On the thirty DAVIS-2016 training
sequences with Gaussian noise added to each channel (128 nodes, ``python -m
bench.tracking --cv "turn_outline=true" --sets davis-train --nodes 128 --noise 8``), J fell
from 0.753 to 0.715 at a deviation of 8 levels and to 0.646 at 16.

So the frame's noise is measured (:func:`noise_level`), and where it is more than clean
video shows (:data:`NOISY_FROM`), the colour image is smoothed by an edge-preserving
bilateral filter whose colour tolerance grows with it (:func:`denoised`) before the colour
models, the lighting and the confidence read it: the same thirty then score 0.733 and
0.729, and the validation five, never tuned on, 0.731 and 0.705 (0.727 and 0.697
before).  The grey frame the motion and the edges are measured on is left as it was (the
motion's corner tracking and the edge search smooth on their own scales), and so are
frames read by their texture (:mod:`engine.tracking.texture`).  No frame of the
thirty-five DAVIS sequences, nor of H.264 video, measures noisy enough to be smoothed: on
clean video nothing changes.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import threading
from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.tracking._frames import repeatable_opencv

__all__ = ["NOISY_FROM", "Smoothing", "denoised", "noise_level"]

GRID: Final = 6
"""Pixels between the points the noise is measured at: 11,000 points at 854 x 480, a
median steady to a few per cent, for about a tenth of a millisecond a frame."""
LAPLACIAN_NORM: Final = 6.0
"""Norm of the difference-of-Laplacians kernel [[1, -2, 1], [-2, 4, -2], [1, -2, 1]]
(the square root of the sum of its squared weights, 36): independent noise of deviation
s gives responses of deviation 6 s, while a plane of any slope gives none (Immerkaer,
"Fast noise variance estimation", CVIU 1996)."""
HALF_NORMAL_MEDIAN: Final = 0.6745
"""Median of |z| for a standard normal z: the median response is 0.6745 x 6 s.  The
median, rather than Immerkaer's mean, reads the flat parts of the frame: edges and texture
are a minority of the points and move it little (on the thirty-five DAVIS sequences the
mean read up to 5.5 levels on clean, textured frames, the median at most 3.2)."""
NOISY_FROM: Final = 5.0
"""Noise (grey levels, one deviation) from which a frame is smoothed: clean video shows or
seems to show at most 3.2 (the frames of the thirty-five DAVIS sequences: hike's and
soccerball's grass and gravel, whose fine texture reads as noise), and under 2 after
H.264 at crf 32; noise of 8 levels added to each channel reads 5.4 and more."""
DIAMETER: Final = 5
"""Pixels across the smoothing's neighbourhood: enough to average noise away (25 pixels),
small enough for about 6.5 ms a 854 x 480 frame, on noisy video only."""
COLOUR_PER_NOISE: Final = 5.0
"""The bilateral filter's colour deviation, in units of :func:`noise_level`: neighbours
whose colour differs by much more weigh little, so a pixel is averaged with its own side of
an edge and the boundary stays where it was.  The grey level's noise is about two thirds
of a channel's, and two pixels' colours differ by noise alone by about 2.5 channel
deviations, so 5 (3.3 channel deviations) averages the noise in full.  Chosen on the
thirty with noise of 8 and 16 levels added (128 nodes, a one-off script: J 0.722 / 0.692
at 3, 0.733 / 0.703 at 5, 0.730 / 0.716 at 8; 0.704 / 0.649 without smoothing) and on
the generated ``noise`` and ``strong_noise`` conditions, seeds 0-5 (0.991 / 0.991 at 5
against 0.992 / 0.992 without; a Gaussian of matching strength blurred their edges: 0.969
and 0.949)."""
SPACE: Final = 3.0
"""Deviation (pixels) of the bilateral filter's spatial weights."""


def noise_level(grey: NDArray[np.uint8]) -> float:
    """The deviation (grey levels) of the frame's pixel noise, from its flat parts.

    Parameters
    ----------
    grey : numpy.ndarray
        H x W uint8 grey frame.

    Returns
    -------
    float
        The median response of the difference-of-Laplacians kernel on a grid of
        :data:`GRID` pixels, scaled to one deviation of independent Gaussian noise
        (:data:`LAPLACIAN_NORM`, :data:`HALF_NORMAL_MEDIAN`); 0 for a frame under 3 x 3.

    Raises
    ------
    ValueError
        If ``grey`` is not a 2-D uint8 array.
    """
    grey = np.asarray(grey)
    if grey.ndim != 2 or grey.dtype != np.uint8:
        raise ValueError(
            f"noise_level takes an H x W uint8 grey frame; got {grey.dtype} of shape {grey.shape}"
        )
    h, w = grey.shape
    if h < 3 or w < 3:
        return 0.0
    from engine.tracking._noise_kernel import median_response

    # the lower median of the integer responses, counted in one compiled pass
    median = median_response(np.ascontiguousarray(grey), GRID)
    return median / (HALF_NORMAL_MEDIAN * LAPLACIAN_NORM)


def denoised(image: NDArray[np.uint8], grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``image`` with its noise (measured on ``grey``) smoothed out, or ``image`` itself.

    Parameters
    ----------
    image : numpy.ndarray
        H x W x 3 BGR (or H x W grey) uint8 frame, contiguous.
    grey : numpy.ndarray
        Its H x W uint8 grey version, which the noise is measured on.

    Returns
    -------
    numpy.ndarray
        ``image`` itself when its :func:`noise_level` is under :data:`NOISY_FROM` (clean
        video); else a new image of the same shape, smoothed by an edge-preserving
        bilateral filter (:data:`DIAMETER`, :data:`COLOUR_PER_NOISE`, :data:`SPACE`).
    """
    noise = noise_level(grey)
    if not noise >= NOISY_FROM:
        return image
    with repeatable_opencv():  # the same smoothing whichever thread or process asks
        smoothed = cv2.bilateralFilter(image, DIAMETER, COLOUR_PER_NOISE * noise, SPACE)
    return np.ascontiguousarray(smoothed, dtype=np.uint8)


class Smoothing:
    """One frame's :func:`denoised` image, made by the first tracker that asks for it.

    Several trackers step on one frame: the objects of an
    :class:`~engine.tracking.ObjectsTracker`, the pieces of a
    :class:`~engine.tracking.PiecesTracker`.  Each would smooth a noisy frame itself
    (about 6.5 ms a 854 x 480 frame); through one ``Smoothing`` the frame is smoothed
    once, and only if some tracker reads its colours (one reading its texture does
    not).  Safe to share between threads.

    Parameters
    ----------
    image, grey : numpy.ndarray
        The frame as :func:`engine.tracking._frames.as_frame` returns it: the
        contiguous H x W x 3 BGR (or H x W grey) uint8 image and its grey version.
    """

    def __init__(self, image: NDArray[np.uint8], grey: NDArray[np.uint8]) -> None:
        self._image, self._grey = image, grey
        self._smoothed: NDArray[np.uint8] | None = None
        self._lock = threading.Lock()

    def of(self, image: NDArray[np.uint8], grey: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """``denoised(image, grey)``: made once for the frame this was made for (the same
        two arrays), anew for any other (a grid has its own,
        :class:`engine.tracking.working.WorkingFrames`)."""
        if image is not self._image or grey is not self._grey:
            return denoised(image, grey)
        with self._lock:
            if self._smoothed is None:
                self._smoothed = denoised(image, grey)
            return self._smoothed
