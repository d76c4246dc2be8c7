"""The robust colour ratio of :mod:`engine.tracking.lighting`, compiled (numba).

Imported lazily; numba caches the machine code on disk.
Kernels use numba's ``error_model="numpy"``: no zero-division check in the
loops, so they vectorise (every divisor is non-zero by construction; the
results are bit for bit those of the default model).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

SCALE = 1024
"""Log-ratio resolution: 1/1024 (0.1 % of brightness), far finer than a grey level."""
LOG = np.round(SCALE * np.log(np.arange(256, dtype=np.float64) + 1.0)).astype(np.int64)
"""``SCALE * log(1 + v)`` of every grey level, as integers (the ratios' histogram bins)."""
RECENTRE_PASSES = 3
"""Times the mean is taken again over the points within ``moved`` of the last mean rather
than of the median.  A step of light below a grey level leaves the median at zero (most
points' levels do not change), and the window around zero then cuts the noise's spread
unevenly: with the window about 1.75 noise deviations wide each way (levels near 50, noise
of 2 levels, ``MOVED`` 10 %), the first mean recovers only two thirds of the step, each
pass two thirds of what is left (1 % after three).  On the generated ``lighting_change``
drawn over 100 frames instead of 40 (the same dimming, slower), the stage had undone 60 %
of it by frame 74, where the track of seed 0 began to shrink away; with three passes, 75 %,
and the track holds to frame 95 (see ``docs/tracking-log.md``)."""
REACH = SCALE // 2
"""Ratios are counted for the first median up to a factor e^(1/2) either way (more
is a cut, not a change of light, and is counted at the end of the range)."""


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _median(histogram: NDArray[np.int32], total: int) -> int:
    """Lower median of the values counted in ``histogram`` (bin k is value k - REACH)."""
    half = (total + 1) // 2
    seen = 0
    for k in range(histogram.shape[0]):
        seen += histogram[k]
        if seen >= half:
            return k - REACH
    return 0


@nb.njit(cache=True, nogil=True, error_model="numpy")
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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def interior(
    inside: NDArray[np.uint8],
    reach: int,
    origin: tuple[int, int],
    stride: int,
    image: NDArray[np.uint8],
) -> tuple[NDArray[np.int64], NDArray[np.uint8]]:
    """The grid points whose (2 reach + 1)^2 neighbourhood in ``inside`` (a mask on the grid,
    1 inside the contour; beyond its edge counts as inside) is all inside: their frame
    ``[x, y]`` (``origin`` + ``stride`` x grid index) and their colours in ``image``."""
    rows, cols = inside.shape
    c = image.shape[2]
    points = np.empty((rows * cols, 2), np.int64)
    colours = np.empty((rows * cols, c), np.uint8)
    m = 0
    for i in range(rows):
        for j in range(cols):
            core = True
            for di in range(max(0, i - reach), min(rows, i + reach + 1)):
                for dj in range(max(0, j - reach), min(cols, j + reach + 1)):
                    if inside[di, dj] == 0:
                        core = False
                        break
                if not core:
                    break
            if not core:
                continue
            x, y = origin[0] + stride * j, origin[1] + stride * i
            points[m, 0], points[m, 1] = x, y
            for ch in range(c):
                colours[m, ch] = image[y, x, ch]
            m += 1
    return points[:m], colours[:m]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def carried(
    points: NDArray[np.int64],
    colours: NDArray[np.uint8],
    matrix: NDArray[np.float64],
    image: NDArray[np.uint8],
) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """The colours of ``points`` ((K, 2) ``[x, y]``, ``colours`` (K, C) where they were) and of
    the nearest pixels of ``image`` (H x W x C) they are carried to by the 2 x 3 ``matrix``,
    for the points carried inside the image: (M, C) before and (M, C) after."""
    h, w, c = image.shape
    k = points.shape[0]
    before = np.empty((k, c), np.uint8)
    after = np.empty((k, c), np.uint8)
    m = 0
    for i in range(k):
        x, y = points[i, 0], points[i, 1]
        u = round(matrix[0, 0] * x + matrix[0, 1] * y + matrix[0, 2])
        v = round(matrix[1, 0] * x + matrix[1, 1] * y + matrix[1, 2])
        if u < 0 or v < 0 or u >= w or v >= h:
            continue
        for ch in range(c):
            before[m, ch] = colours[i, ch]
            after[m, ch] = image[v, u, ch]
        m += 1
    return before[:m], after[:m]


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _near_sum(
    ratios: NDArray[np.int32], centre: NDArray[np.float64], moved: int, sums: NDArray[np.int64]
) -> int:
    """How many rows of ``ratios`` lie within ``moved`` of ``centre`` on every channel; their
    sum per channel into ``sums``."""
    sums[:] = 0
    count = 0
    for i in range(ratios.shape[0]):
        near = True
        for ch in range(ratios.shape[1]):
            if abs(ratios[i, ch] - centre[ch]) > moved:
                near = False
                break
        if near:
            count += 1
            for ch in range(ratios.shape[1]):
                sums[ch] += ratios[i, ch]
    return count


@nb.njit(cache=True, nogil=True, error_model="numpy")
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
    the light).  First the median ratio of all of them; then, the mean of those
    within ``moved`` (in ``table``'s units) of it on every channel: a point whose
    colour changed otherwise moved, or something moved over it.  The mean and not
    a second median, because a step of light below one level leaves many points'
    levels unchanged: their median sticks at zero while their mean does not.  The
    mean is then taken again over the points within ``moved`` of the last mean,
    :data:`RECENTRE_PASSES` times: a window left around a median stuck at zero cuts
    the noise unevenly and holds the mean back towards zero.

    Returns
    -------
    count : int
        Points of the mean.
    step : numpy.ndarray
        (C,) float64 natural-log ratios (0 where ``count`` is 0).
    """
    k, c = before.shape
    ratios = np.empty((k, c), np.int32)
    first = np.zeros((c, 2 * REACH + 1), np.int32)
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
    centre = np.empty(c, np.float64)
    for ch in range(c):
        centre[ch] = _median(first[ch], total)
    sums = np.zeros(c, np.int64)
    kept = _near_sum(ratios[:total], centre, moved, sums)
    if kept == 0:
        return 0, step
    again = np.empty(c, np.int64)
    for _ in range(RECENTRE_PASSES):
        for ch in range(c):
            centre[ch] = sums[ch] / kept
        count = _near_sum(ratios[:total], centre, moved, again)
        if count == 0:  # no point near the mean on every channel: keep the last mean
            break
        if count == kept and (again == sums).all():  # the same points: settled
            break
        sums[:] = again
        kept = count
    for ch in range(c):
        step[ch] = sums[ch] / (kept * SCALE)
    return kept, step
