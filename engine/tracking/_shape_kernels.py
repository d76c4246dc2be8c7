"""Compiled comparison of a shape with the recent ones (:mod:`engine.tracking.recent_shapes`).

Each shape is a boolean grid (:func:`engine.tracking.confidence.shape_mask`); numpy's
``count_nonzero(stack | shape, axis=(1, 2))`` and its ``&`` twin make two temporaries of
the whole stack and count them through a cast to integers.  One pass counts both.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["best_overlap"]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def best_overlap(
    stack: NDArray[np.bool_], kept: NDArray[np.bool_], shape: NDArray[np.bool_]
) -> float:
    """The largest IoU of ``shape`` (H x W) with any of ``stack``'s (K x H x W) grids
    ``k`` where ``kept[k]`` (at least one): ``common / max(union, 1)`` each, as numpy
    divides two integer counts."""
    best = 0.0
    first = True
    for k in range(stack.shape[0]):
        if not kept[k]:
            continue
        common = 0
        union = 0
        for i in range(shape.shape[0]):
            for j in range(shape.shape[1]):
                a, b = stack[k, i, j], shape[i, j]
                common += a and b
                union += a or b
        value = common / max(union, 1)
        if first or value > best:
            best = value
        first = False
    return best
