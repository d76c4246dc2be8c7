"""Compiled contour geometry (numba): self-crossing, normals, nearest points, resampling and the
least-squares similarity.

Imported lazily so that ``import engine.geometry`` does not start the
compiler; numba caches the machine code on disk.
Kernels use numba's ``error_model="numpy"``: no zero-division check in the
loops, so they vectorise (every divisor is non-zero by construction; the
results are bit for bit those of the default model).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from engine.geometry._pairwise import pairwise_sum


@nb.njit(cache=True, nogil=True, error_model="numpy")
def polyline_crosses(points: NDArray[np.float64], closed: bool) -> bool:
    """Whether two non-adjacent edges of the polyline through ``points`` cross."""
    n = points.shape[0]
    m = n if closed else n - 1
    for i in range(m):
        ax, ay = points[i, 0], points[i, 1]
        bx, by = points[(i + 1) % n, 0], points[(i + 1) % n, 1]
        dx, dy = bx - ax, by - ay
        for j in range(i + 2, m):
            if closed and i == 0 and j == m - 1:
                continue  # the last edge shares node 0 with the first
            cx, cy = points[j, 0], points[j, 1]
            ex, ey = points[(j + 1) % n, 0], points[(j + 1) % n, 1]
            o1 = dx * (cy - ay) - dy * (cx - ax)
            o2 = dx * (ey - ay) - dy * (ex - ax)
            if o1 * o2 >= 0.0:
                continue
            fx, fy = ex - cx, ey - cy
            o3 = fx * (ay - cy) - fy * (ax - cx)
            o4 = fx * (by - cy) - fy * (bx - cx)
            if o3 * o4 < 0.0:
                return True
    return False


@nb.njit(cache=True, nogil=True, error_model="numpy")
def perimeter(nodes: NDArray[np.float64]) -> float:
    """Length of the closed polygon through (N >= 1, 2) ``nodes``, as numpy's
    ``norm(diff(closed), axis=1).sum()`` gives it (see engine.geometry.perimeter)."""
    n = nodes.shape[0]
    lengths = np.empty(n)
    for i in range(n):
        k = (i + 1) % n
        dx, dy = nodes[k, 0] - nodes[i, 0], nodes[k, 1] - nodes[i, 1]
        lengths[i] = math.sqrt(dx * dx + dy * dy)
    return float(pairwise_sum(lengths))


@nb.njit(cache=True, nogil=True, error_model="numpy")
def outward_normals(nodes: NDArray[np.float64]) -> NDArray[np.float64]:
    """Unit normals of a closed contour pointing out of it (see engine.geometry.outward_normals)."""
    n = nodes.shape[0]
    area = 0.0
    for i in range(n):
        k = (i + 1) % n
        area += nodes[i, 0] * nodes[k, 1] - nodes[i, 1] * nodes[k, 0]
    sign = 1.0 if area >= 0.0 else -1.0
    out = np.empty((n, 2))
    for i in range(n):
        tx = nodes[(i + 1) % n, 0] - nodes[(i - 1) % n, 0]
        ty = nodes[(i + 1) % n, 1] - nodes[(i - 1) % n, 1]
        length = max(math.sqrt(tx * tx + ty * ty), 1e-9)
        out[i, 0] = sign * ty / length
        out[i, 1] = -sign * tx / length
    return out


SWEEP_FROM = 256
"""Fewest points for :func:`nearest` to sweep them in x order rather than scan them all.
Within a frame's work (its caches and branch history taken by the rest) the sweep saves
10-15 us of the scan's 40 among the 512 points of a densely resampled outline, and costs
5 us more than the scan's 12 among a contour's 128 nodes."""


@nb.njit(cache=True, nogil=True, error_model="numpy")
def nearest(queries: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index of the nearest of ``points`` to each query (see engine.geometry.nearest).

    The points sorted by x, each query looks outward from its own x and stops where the
    x distance alone exceeds the best squared distance found; the search starts from the
    last query's answer and its neighbours (consecutive queries along a contour are
    near each other), so few points are read.  The distances are the scan's, ``dx * dx +
    dy * dy``, and equal ones go to the lowest index, so the answer is the scan's
    (:func:`nearest_scan`, which non-finite coordinates and few points still take).
    """
    n = points.shape[0]
    finite = True
    for i in range(n):
        finite &= math.isfinite(points[i, 0]) and math.isfinite(points[i, 1])
    for q in range(queries.shape[0]):
        finite &= math.isfinite(queries[q, 0]) and math.isfinite(queries[q, 1])
    if n < SWEEP_FROM or not finite:
        return nearest_scan(queries, points)
    order = np.argsort(points[:, 0], kind="mergesort")
    xs = points[order, 0]
    found = np.empty(queries.shape[0], dtype=np.int64)
    last = 0
    for q in range(queries.shape[0]):
        qx, qy = queries[q, 0], queries[q, 1]
        best, where = np.inf, n
        for step in range(-2, 3):  # the last answer and its neighbours along the points
            i = (last + step) % n
            dx, dy = points[i, 0] - qx, points[i, 1] - qy
            d = dx * dx + dy * dy
            if d < best or (d == best and i < where):
                best, where = d, i
        start = np.searchsorted(xs, qx)
        for direction in (1, -1):
            k = start if direction > 0 else start - 1
            while 0 <= k < n:
                dx = xs[k] - qx
                if dx * dx > best:
                    break
                i = order[k]
                dy = points[i, 1] - qy
                d = dx * dx + dy * dy
                if d < best or (d == best and i < where):
                    best, where = d, i
                k += direction
        found[q] = where
        last = where
    return found


@nb.njit(cache=True, nogil=True, error_model="numpy")
def nearest_scan(queries: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index of the nearest of ``points`` to each query, every point read (the first of
    equally near ones; NaN distances never win)."""
    found = np.empty(queries.shape[0], dtype=np.int64)
    for q in range(queries.shape[0]):
        qx, qy = queries[q, 0], queries[q, 1]
        best, where = np.inf, 0
        for i in range(points.shape[0]):
            dx, dy = points[i, 0] - qx, points[i, 1] - qy
            d = dx * dx + dy * dy
            if d < best:
                best, where = d, i
        found[q] = where
    return found


@nb.njit(cache=True, nogil=True, error_model="numpy")
def resample_polyline(points: NDArray[np.float64], count: int, closed: bool) -> NDArray[np.float64]:
    """``count`` points evenly spaced by arc length (see engine.geometry.resample).

    Each step as numpy takes it there (``hypot``, a running sum, ``linspace``'s
    ``k * step``, ``interp``'s ``slope * (x - xp[j]) + fp[j]`` on the interval
    ``xp[j] <= x < xp[j + 1]``), so the result is numpy's bit for bit, without
    a dozen whole-array calls for a 128-node contour.
    """
    n = points.shape[0]
    m = n + 1 if closed else n
    arc = np.empty(m)
    arc[0] = 0.0
    for i in range(1, m):
        a, b = points[i - 1], points[i % n]
        arc[i] = arc[i - 1] + math.hypot(b[0] - a[0], b[1] - a[1])
    total = arc[m - 1]
    out = np.empty((count, 2))
    if not total > 0.0:
        for k in range(count):
            out[k, 0], out[k, 1] = points[0, 0], points[0, 1]
        return out
    div = count if closed else count - 1
    step = total / div if div > 0 else 0.0
    j = 0
    for k in range(count):
        if div <= 0:
            x = k * total
        elif step == 0.0:  # numpy's denormal branch
            x = (k / div) * total
        else:
            x = k * step
        x += 0.0
        if not closed and k == count - 1 and count > 1:
            x = total
        if x >= total:
            last = points[(m - 1) % n]
            out[k, 0], out[k, 1] = last[0], last[1]
            continue
        while j + 1 < m - 1 and arc[j + 1] <= x:
            j += 1
        while j > 0 and arc[j] > x:
            j -= 1
        a, b = points[j], points[(j + 1) % n]
        span = arc[j + 1] - arc[j]
        for c in range(2):
            slope = (b[c] - a[c]) / span
            value = slope * (x - arc[j]) + a[c]
            if math.isnan(value):  # as numpy: from the other end, or the flat value
                value = slope * (x - arc[j + 1]) + b[c]
                if math.isnan(value) and a[c] == b[c]:
                    value = a[c]
            out[k, c] = value
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def least_squares_similarity(
    src: NDArray[np.float64], dst: NDArray[np.float64], use: NDArray[np.bool_]
) -> tuple[NDArray[np.float64], bool]:
    """The 2 x 3 similarity ``[[a, -b, tx], [b, a, ty]]`` minimising the summed squared
    distances from the moved ``src[use]`` to ``dst[use]``, in closed form (centred sums).
    The flag is False (and the matrix zero) with fewer than two distinct points."""
    out = np.zeros((2, 3))
    n = 0
    sx = sy = dx = dy = 0.0
    for i in range(src.shape[0]):
        if use[i]:
            n += 1
            sx += src[i, 0]
            sy += src[i, 1]
            dx += dst[i, 0]
            dy += dst[i, 1]
    if n < 2:
        return out, False
    sx /= n
    sy /= n
    dx /= n
    dy /= n
    spread = dot = cross = 0.0
    for i in range(src.shape[0]):
        if use[i]:
            px, py = src[i, 0] - sx, src[i, 1] - sy
            qx, qy = dst[i, 0] - dx, dst[i, 1] - dy
            spread += px * px + py * py
            dot += px * qx + py * qy
            cross += px * qy - py * qx
    if not spread > 0.0:
        return out, False
    a = dot / spread
    b = cross / spread
    out[0, 0], out[0, 1], out[0, 2] = a, -b, dx - (a * sx - b * sy)
    out[1, 0], out[1, 1], out[1, 2] = b, a, dy - (b * sx + a * sy)
    return out, True


@nb.njit(cache=True, nogil=True, error_model="numpy")
def extent(nodes: NDArray[np.float64]) -> tuple[float, float, float, float]:
    """``(min x, min y, max x, max y)`` of (N >= 1, 2) points; NaN ones if any is NaN (as
    numpy's ``min`` and ``max`` would give)."""
    x0, y0 = nodes[0, 0], nodes[0, 1]
    x1, y1 = x0, y0
    for i in range(nodes.shape[0]):
        x, y = nodes[i, 0], nodes[i, 1]
        if x != x or y != y:
            return math.nan, math.nan, math.nan, math.nan
        x0, x1 = min(x0, x), max(x1, x)
        y0, y1 = min(y0, y), max(y1, y)
    return x0, y0, x1, y1


@nb.njit(cache=True, nogil=True, error_model="numpy")
def fixed_point(nodes: NDArray[np.float64], scale: float, limit: float) -> NDArray[np.int32]:
    """(N, 1, 2) int32 ``round(clip(nodes, -limit, limit) * scale)`` (half to even, as
    ``numpy.round``), or (0, 1, 2) when a node is not finite."""
    n = nodes.shape[0]
    out = np.empty((n, 1, 2), np.int32)
    for i in range(n):
        for k in range(2):
            v = nodes[i, k]
            if not math.isfinite(v):
                return out[:0]
            out[i, 0, k] = np.int32(np.rint(min(max(v, -limit), limit) * scale))
    return out
