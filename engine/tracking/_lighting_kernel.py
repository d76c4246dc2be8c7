"""The robust colour ratio of :mod:`engine.tracking.lighting`, compiled (numba).

Imported lazily; numba caches the machine code on disk.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

SCALE = 1024
"""Log-ratio resolution: 1/1024 (0.1 % of brightness), far finer than a grey level."""
LOG = np.round(SCALE * np.log(np.arange(256, dtype=np.float64) + 1.0)).astype(np.int64)
"""``SCALE * log(1 + v)`` of every grey level, as integers (the ratios' histogram bins)."""
REACH = SCALE // 2
"""Ratios are counted for the first median up to a factor e^(1/2) either way (more
is a cut, not a change of light, and is counted at the end of the range)."""


@nb.njit(cache=True, nogil=True, inline="always")
def _median(histogram: NDArray[np.int64], total: int) -> int:
    """Lower median of the values counted in ``histogram`` (bin k is value k - REACH)."""
    half = (total + 1) // 2
    seen = 0
    for k in range(histogram.shape[0]):
        seen += histogram[k]
        if seen >= half:
            return k - REACH
    return 0


@nb.njit(cache=True, nogil=True)
def grid_sample(image: NDArray[np.uint8], grid: int) -> NDArray[np.uint8]:
    """(K, C) colours of an H x W x C image at every ``grid``-th pixel from ``grid // 2``."""
    h, w, c = image.shape
    rows = (h - grid // 2 + grid - 1) // grid
    cols = (w - grid // 2 + grid - 1) // grid
    out = np.empty((rows * cols, c), np.uint8)
    k = 0
    for i in range(grid // 2, h, grid):
        for j in range(grid // 2, w, grid):
            for ch in range(c):
                out[k, ch] = image[i, j, ch]
            k += 1
    return out


@nb.njit(cache=True, nogil=True)
def ratio_step(
    before: NDArray[np.uint8],
    after: NDArray[np.uint8],
    table: NDArray[np.int64],
    dark: int,
    bright: int,
    moved: int,
) -> tuple[int, NDArray[np.float64]]:
    """Per channel, the mean log ratio ``log(after / before)`` of pixels that only changed light.

    ``before`` and ``after`` are (K, C) uint8 colours of the same K points in two
    frames.  A point counts where every channel of both is strictly between
    ``dark`` and ``bright`` (clipped or noise-dominated levels say nothing about
    the light).  First the median ratio of all of them; then, the median of those
    within ``moved`` (in ``table``'s units) of it on every channel: a point whose
    colour changed otherwise moved, or something moved over it.  The mean and not
    a second median, because a step of light below one level leaves many points'
    levels unchanged: their median sticks at zero while their mean does not.

    Returns
    -------
    count : int
        Points of the mean.
    step : numpy.ndarray
        (C,) float64 natural-log ratios (0 where ``count`` is 0).
    """
    k, c = before.shape
    ratios = np.empty((k, c), np.int64)
    first = np.zeros((c, 2 * REACH + 1), np.int64)
    total = 0
    for i in range(k):
        ok = True
        for ch in range(c):
            a, b = before[i, ch], after[i, ch]
            if a <= dark or a >= bright or b <= dark or b >= bright:
                ok = False
                break
        if not ok:
            continue
        for ch in range(c):
            d = table[after[i, ch]] - table[before[i, ch]]
            ratios[total, ch] = d
            first[ch, min(max(d, -REACH), REACH) + REACH] += 1
        total += 1
    step = np.zeros(c, np.float64)
    if total == 0:
        return 0, step
    centre = np.empty(c, np.int64)
    for ch in range(c):
        centre[ch] = _median(first[ch], total)
    sums = np.zeros(c, np.int64)
    kept = 0
    for i in range(total):
        near = True
        for ch in range(c):
            if abs(ratios[i, ch] - centre[ch]) > moved:
                near = False
                break
        if near:
            kept += 1
            for ch in range(c):
                sums[ch] += ratios[i, ch]
    if kept == 0:
        return 0, step
    for ch in range(c):
        step[ch] = sums[ch] / (kept * SCALE)
    return kept, step
