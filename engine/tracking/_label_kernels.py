"""Compiled counts over labelled pixels and sampled colours: single passes where numpy
makes temporaries of a whole region.

:func:`label_shares` serves the cut's choice of its main piece
(:mod:`engine.tracking.segmentation`), :func:`colour_spread` the test for grey frames
(:func:`engine.tracking.texture.is_grey`).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["colour_spread", "label_shares"]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def label_shares(
    labels: NDArray[np.int32], prior: NDArray[np.uint8], count: int
) -> tuple[NDArray[np.int64], int]:
    """Per label ``0 .. count - 1``, its pixels where ``prior`` is set, and how many
    pixels ``prior`` sets: ``np.bincount(labels[prior > 0], minlength=count)`` and
    ``np.count_nonzero(prior)``, in one pass (labels in ``[0, count)``)."""
    shares = np.zeros(count, np.int64)
    total = 0
    h, w = labels.shape
    for y in range(h):
        for x in range(w):
            if prior[y, x]:
                shares[labels[y, x]] += 1
                total += 1
    return shares, total


@nb.njit(cache=True, nogil=True, error_model="numpy")
def colour_spread(image: NDArray[np.uint8], step: int, tolerance: int) -> bool:
    """Whether a pixel of ``image[::step, ::step]`` (H x W x C) has channels further apart
    than ``tolerance`` levels: numpy's ``(max - min).max() > tolerance`` over the
    channels, stopping at the first such pixel."""
    h, w, c = image.shape
    for y in range(0, h, step):
        for x in range(0, w, step):
            low = high = int(image[y, x, 0])
            for k in range(1, c):
                v = int(image[y, x, k])
                low, high = min(low, v), max(high, v)
            if high - low > tolerance:
                return True
    return False
