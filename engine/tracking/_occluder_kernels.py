"""Compiled loops (numba) of the colour test of covered pieces.

The colour histograms of :func:`engine.tracking.occlusion.piece_overlaps`: a ring
round the object and the pieces the occlusion rule took for covered, each in one
pass over its pixels.  Imported lazily, like :mod:`engine.tracking._image_kernels`,
whose :func:`~engine.tracking._image_kernels.pixel_bin` bins the colours.  Images
are indexed ``[y, x]``; origins are ``(x, y)``.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from engine.tracking._image_kernels import pixel_bin


@nb.njit(cache=True, nogil=True, error_model="numpy")
def ring_histogram(
    image: NDArray[np.uint8],
    origin: tuple[int, int],
    step: int,
    wide: NDArray[np.uint8],
    inside: NDArray[np.uint8],
    left_out: NDArray[np.uint8],
    bits: int,
) -> NDArray[np.int64]:
    """Colour counts of a ring: ``wide`` non-zero, ``inside`` and ``left_out`` zero.

    The three masks lie on a grid of every ``step``-th pixel of ``image`` (H x W x
    1 grey or H x W x 3 BGR, binned at ``bits`` a channel) from ``origin``
    ``(x, y)`` on: grid cell ``(i, j)`` is pixel ``(origin[1] + step * i,
    origin[0] + step * j)``.
    """
    ox, oy = origin
    bins = 1 << bits if image.shape[2] == 1 else 1 << (3 * bits)
    out = np.zeros(bins, np.int64)
    h, w = wide.shape
    for i in range(h):
        for j in range(w):
            if wide[i, j] != 0 and inside[i, j] == 0 and left_out[i, j] == 0:
                out[pixel_bin(image, oy + step * i, ox + step * j, bits, bits)] += 1
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def label_histograms(
    image: NDArray[np.uint8],
    origin: tuple[int, int],
    labels: NDArray[np.int32],
    count: int,
    least: int,
    bits: int,
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int32]]:
    """Colour counts of the labelled pieces of at least ``least`` pixels.

    ``labels[i, j]`` (0: no piece, else 1 to ``count - 1``) labels pixel
    ``(origin[1] + i, origin[0] + j)`` of ``image`` (H x W x 1 grey or H x W x 3
    BGR, binned at ``bits`` a channel).  Returns a row of counts for each piece
    so large, in label order, their sizes, and ``labels`` renumbered: 1, 2, ...
    for those pieces in that order, 0 for the others.
    """
    ox, oy = origin
    h, w = labels.shape
    sizes = np.zeros(count, np.int64)
    where = np.empty(h * w, np.int64)  # the labelled pixels: pages touched only if used
    found = 0
    for i in range(h):
        for j in range(w):
            k = labels[i, j]
            if k > 0:
                sizes[k] += 1
                where[found] = i * w + j
                found += 1
    rows = np.zeros(count, np.int64)
    large = 0
    for k in range(1, count):
        if sizes[k] >= least:
            large += 1
            rows[k] = large
    bins = 1 << bits if image.shape[2] == 1 else 1 << (3 * bits)
    out = np.zeros((large, bins), np.int64)
    kept = np.zeros(large, np.int64)
    judged = np.zeros((h, w), np.int32)
    for k in range(1, count):
        if rows[k] > 0:
            kept[rows[k] - 1] = sizes[k]
    for n in range(found):
        i, j = where[n] // w, where[n] % w
        row = rows[labels[i, j]]
        if row > 0:
            out[row - 1, pixel_bin(image, oy + i, ox + j, bits, bits)] += 1
            judged[i, j] = row
    return out, kept, judged
