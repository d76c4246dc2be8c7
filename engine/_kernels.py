"""Compiled inner loops (numba) for the O(N) exact solver.

Imported lazily by :mod:`engine.recursive` so that ``import engine`` stays
light; numba compiles on first use and caches the machine code on disk.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray


@nb.njit(cache=True, nogil=True, fastmath={"contract"})
def solve_chain(
    F: NDArray[np.float64],
    r: float,
    inv_s: float,
    closed: bool,
    r_n: float,
    inv_den: float,
    head: int,
    out: NDArray[np.float64],
) -> bool:
    """Two first-order recursions per contour and coordinate (see recursive.py).

    F and out have shape (B, N, 2).  Returns False when a carry is not finite,
    i.e. when a force was not finite or the result overflowed.
    """
    n_batch, n = F.shape[0], F.shape[1]
    ok = True
    for b in range(n_batch):
        # Weighted sums of the first and last `head` forces: the start values
        # of the recursions (the rest of the periodic sums is below rounding).
        h0 = 0.0
        h1 = 0.0
        t0 = 0.0
        t1 = 0.0
        w = 1.0
        for m in range(head):
            h0 += w * F[b, m, 0]
            h1 += w * F[b, m, 1]
            t0 += w * F[b, n - 1 - m, 0]
            t1 += w * F[b, n - 1 - m, 1]
            w *= r
        if closed:
            c0 = t0 * inv_den
            c1 = t1 * inv_den
            b0 = h0 * inv_den
            b1 = h1 * inv_den
        else:  # mirrored ring of 2N nodes
            c0 = (h0 + r_n * t0) * inv_den
            c1 = (h1 + r_n * t1) * inv_den
            b0 = (t0 + r_n * h0) * inv_den
            b1 = (t1 + r_n * h1) * inv_den
        for i in range(n):
            c0 = F[b, i, 0] + r * c0
            c1 = F[b, i, 1] + r * c1
            out[b, i, 0] = c0
            out[b, i, 1] = c1
        for i in range(n - 1, -1, -1):
            f0 = F[b, i, 0]
            f1 = F[b, i, 1]
            b0 = f0 + r * b0
            b1 = f1 + r * b1
            out[b, i, 0] = (out[b, i, 0] + b0 - f0) * inv_s
            out[b, i, 1] = (out[b, i, 1] + b1 - f1) * inv_s
        if not (
            math.isfinite(c0) and math.isfinite(c1) and math.isfinite(b0) and math.isfinite(b1)
        ):
            ok = False
    return ok


@nb.njit(cache=True, nogil=True)
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


@nb.njit(cache=True, nogil=True)
def colour_bins(image: NDArray[np.uint8], grey_bits: int, colour_bits: int) -> NDArray[np.uint16]:
    """Histogram bin of every pixel in one pass (see engine.appearance.quantise)."""
    h, w = image.shape[0], image.shape[1]
    out = np.empty((h, w), dtype=np.uint16)
    if image.ndim == 2:
        shift = 8 - grey_bits
        for i in range(h):
            for j in range(w):
                out[i, j] = image[i, j] >> shift
    else:
        shift = 8 - colour_bits
        for i in range(h):
            for j in range(w):
                b = image[i, j, 0] >> shift
                g = image[i, j, 1] >> shift
                r = image[i, j, 2] >> shift
                out[i, j] = (np.uint16(b) << (2 * colour_bits)) | (np.uint16(g) << colour_bits) | r
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _bilinear(image: NDArray[np.float32], x: float, y: float) -> float:
    """Bilinear sample with replicated borders (as cv2.BORDER_REPLICATE)."""
    h, w = image.shape
    x = min(max(x, 0.0), w - 1.0)
    y = min(max(y, 0.0), h - 1.0)
    x0 = min(int(x), w - 2) if w > 1 else 0
    y0 = min(int(y), h - 2) if h > 1 else 0
    x1 = min(x0 + 1, w - 1)
    y1 = min(y0 + 1, h - 1)
    fx = x - x0
    fy = y - y0
    top = image[y0, x0] * (1.0 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1.0 - fx) + image[y1, x1] * fx
    return float(top * (1.0 - fy) + bottom * fy)


@nb.njit(cache=True, nogil=True)
def boundary_search(
    prob: NDArray[np.float32],
    edges: NDArray[np.float32],
    nodes: NDArray[np.float64],
    normals: NDArray[np.float64],
    radius: int,
    region_weight: float,
    edge_weight: float,
    distance_penalty: float,
    offset: NDArray[np.float64],
    strength: NDArray[np.float64],
) -> float:
    """Per-node best object-to-background split along the normal (image_forces).

    ``nodes`` are in the maps' pixel coordinates.  Fills ``offset`` and
    ``strength``; returns the mean inside-minus-outside probability.
    """
    k = 2 * radius + 1
    q = np.empty(k)
    e = np.empty(k)
    contrast = 0.0
    for n in range(nodes.shape[0]):
        total = 0.0
        inside = 0.0
        outside = 0.0
        for j in range(k):
            step = j - radius
            x = nodes[n, 0] + step * normals[n, 0]
            y = nodes[n, 1] + step * normals[n, 1]
            p = _bilinear(prob, x, y)
            e[j] = _bilinear(edges, x, y)
            q[j] = p - 0.5
            total += q[j]
            if j <= radius:
                inside += p
            if j >= radius:
                outside += p
        contrast += (inside - outside) / (radius + 1)
        best = -1e300
        best_j = 0
        before = 0.0
        for j in range(k - 1):
            before += q[j]
            position = j + 0.5 - radius
            score = (
                region_weight * (2.0 * before - total) / (k / 2.0)
                + edge_weight * 0.5 * (e[j] + e[j + 1])
                - distance_penalty * abs(position) / max(radius, 1)
            )
            if score > best:
                best = score
                best_j = j
        offset[n] = best_j + 0.5 - radius
        strength[n] = min(max(best, 0.0), 1.0)
    return float(contrast / max(nodes.shape[0], 1))
