"""The prediction aligned to the appearance: a translation search of its silhouette.

The motion model moves the last contour by the object's similarity
(:class:`engine.tracking.prediction.FlowMotion`), measured from points tracked
between the two frames.  When those points go wrong together (a dog jumping
across a striped hurdle, a duck's blurred wings, a rider's back in motion blur),
the prediction lags or overshoots the object by more than the band the cut
relabels (``cut_band``), and the cut cannot bring it back: it only decides the
pixels within the band.

So before the refinement and the cut, the predicted silhouette is slid over the
frame's p(object) (the cue maps' colour model with the motion contrast): the
translation ``t`` within :data:`REACH` pixels that maximises

    S(t) = sum over the silhouette moved by t of (2 p - 1)

(object-like pixels count +1, background-like -1) replaces no translation when
it is better by at least :data:`GAIN` per pixel of the silhouette.  This is a
correlation (``cv2.matchTemplate``) of the silhouette with the map, made at a
reduced resolution so that it costs a fraction of a millisecond at any object
size: the silhouette's larger side is brought to about :data:`SIDE` pixels.  The
cut then places the boundary to the pixel.  It is a second opinion on the
motion from a different cue (where the object's colours are, not how its
texture moved), asked only for a shift: the shape stays the prediction's.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Final

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes, contour_to_mask, extent
from engine.tracking.maps import Maps
from engine.tracking.stages import Prediction

__all__ = ["GAIN", "MIN_AREA", "REACH", "SIDE", "align_to_appearance", "aligned"]

REACH: Final = 8
"""Largest shift (frame pixels, each way in x and y) the search tries: a cut's band
(``cut_band`` 8) beyond what the motion model predicted.  On the thirty training
sequences over five node counts, searched at full resolution, J 0.7475 with 8, 0.7471
with 16 and 0.7451 with 24 (0.7420 without the alignment; ``docs/tracking-log.md``): a
farther reach also finds other object-coloured things.  In blocks, as here: 0.7457."""
GAIN: Final = 0.05
"""Least gain of ``S`` per silhouette pixel (``2 p - 1`` is in [-1, 1]) for a shift to
be taken: about 3 % of its pixels turned from clearly background (p 0.1) to clearly
object (p 0.9), each gaining 1.6.  The
thirty: 0.7458 / 0.7471 / 0.7405 with 0.02 / 0.05 / 0.15 (at full resolution, a reach of
16); any gain at all, in blocks: 0.7441."""
SIDE: Final = 48
"""The silhouette's larger side (pixels) at the resolution the search runs at: a
large object is searched on p(object) averaged over blocks of ``round(size / 48)``
pixels, so the correlation costs about the same for every object."""
MIN_AREA: Final = 50
"""Fewest silhouette pixels (at the search's resolution) to align: fewer say too
little about where the object is."""


def align_to_appearance(
    probability: NDArray[np.float32],
    origin: tuple[int, int],
    nodes: NDArray[np.float64],
    *,
    reach: int = REACH,
    gain: float = GAIN,
) -> NDArray[np.float64] | None:
    """The shift ``[dx, dy]`` that puts the silhouette on object-like pixels, or None.

    Parameters
    ----------
    probability : numpy.ndarray
        H x W float32 p(object) of a region of the frame (the cue maps').
    origin : tuple of int
        ``(x, y)`` of the region's top-left pixel in the frame.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` frame pixels: the predicted contour (closed).
    reach : int
        Largest shift tried (frame pixels, each way in x and y).
    gain : float
        Least gain per silhouette pixel (see the module's docstring).

    Returns
    -------
    numpy.ndarray or None
        float64 ``[dx, dy]`` frame pixels (a multiple of the search's block size),
        or None when no shift gains enough, the silhouette is too small, or the
        search would leave the region.

    Raises
    ------
    ValueError
        If ``probability`` is not a 2-D array, ``nodes`` are not at least 3
        finite ``[x, y]`` points, ``reach`` is not a positive integer, or ``gain``
        is not a finite number at least 0.
    """
    p = np.asarray(probability, np.float32)
    if p.ndim != 2:
        raise ValueError(f"probability must be an H x W map; got shape {p.shape}")
    if isinstance(reach, bool) or not isinstance(reach, int) or reach < 1:
        raise ValueError(f"reach must be a positive integer; got {reach!r}")
    if isinstance(gain, bool) or not isinstance(gain, int | float) or not gain >= 0:
        raise ValueError(f"gain must be a number at least 0; got {gain!r}")
    if not math.isfinite(gain):
        raise ValueError(f"gain must be finite; got {gain!r}")
    local = as_nodes(nodes) - np.asarray(origin, np.float64)
    low_x, low_y, high_x, high_y = extent(local)
    block = max(1, round(max(high_x - low_x, high_y - low_y) / SIDE))
    if block > 1:  # pixel u of the blocks covers pixels block * u .. block * u + block - 1
        local = (local + 0.5) / block - 0.5
        low_x, low_y, high_x, high_y = extent(local)
    r = math.ceil(reach / block)
    x0, y0 = math.floor(low_x) - 1, math.floor(low_y) - 1
    x1, y1 = math.ceil(high_x) + 2, math.ceil(high_y) + 2
    if x0 - r < 0 or y0 - r < 0 or x1 + r > p.shape[1] // block or y1 + r > p.shape[0] // block:
        return None  # at the region's (the frame's) edge: no evidence beyond it
    silhouette = contour_to_mask(local - [x0, y0], (y1 - y0, x1 - x0)) > 0
    area = int(np.count_nonzero(silhouette))
    if area < MIN_AREA:
        return None
    window = p[block * (y0 - r) : block * (y1 + r), block * (x0 - r) : block * (x1 + r)]
    if block > 1:  # only the window, averaged over blocks
        size = (x1 - x0 + 2 * r, y1 - y0 + 2 * r)
        window = np.asarray(cv2.resize(window, size, interpolation=cv2.INTER_AREA), np.float32)
    sums = cv2.matchTemplate(2.0 * window - 1.0, silhouette.astype(np.float32), cv2.TM_CCORR)
    best = np.unravel_index(int(np.argmax(sums)), sums.shape)
    if (sums[best] - sums[r, r]) / area < gain:
        return None
    return np.array([best[1] - r, best[0] - r], np.float64) * block


def aligned(prediction: Prediction, maps: Maps) -> Prediction:
    """``prediction`` shifted by :func:`align_to_appearance` over ``maps.probability``.

    The predicted contour, its rigidly moved silhouette and the similarity's
    translation all move by the shift; the prediction itself is returned when no
    shift gains enough.  ``maps`` is the cue maps' region around the prediction
    (:meth:`engine.tracking.stages.BoundaryCues.maps`), with the motion contrast
    in its p(object) when the tracker uses it.
    """
    shift = align_to_appearance(maps.probability, maps.origin, prediction.nodes)
    if shift is None:
        return prediction
    matrix = prediction.matrix.copy()
    matrix[:, 2] += shift
    return dataclasses.replace(
        prediction, nodes=prediction.nodes + shift, rigid=prediction.rigid + shift, matrix=matrix
    )
