"""Compiled per-pixel and per-node loops (numba) of the tracker's image work.

Each kernel fuses what would otherwise be several whole-array passes (and
several temporary arrays the size of the region of interest) into one.
Imported lazily, like :mod:`engine.physics._kernels`; numba caches the machine code
on disk.  Coordinates are ``[x, y]`` pixels; images are indexed ``[y, x]``.
Kernels use numba's ``error_model="numpy"``: no zero-division check in the
loops, so they vectorise (every divisor is non-zero by construction; the
results are bit for bit those of the default model).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from engine.geometry._kernels import outward_normals


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def pixel_bin(image: NDArray[np.uint8], i: int, j: int, grey_bits: int, colour_bits: int) -> int:
    """Bin of pixel (i, j) of an H x W x 1 (grey) or H x W x 3 (BGR) image."""
    if image.shape[2] == 1:
        return int(image[i, j, 0]) >> (8 - grey_bits)
    shift = 8 - colour_bits
    b = int(image[i, j, 0]) >> shift
    g = int(image[i, j, 1]) >> shift
    r = int(image[i, j, 2]) >> shift
    return (b << (2 * colour_bits)) | (g << colour_bits) | r


@nb.njit(cache=True, nogil=True, error_model="numpy")
def colour_bins(image: NDArray[np.uint8], grey_bits: int, colour_bits: int) -> NDArray[np.uint16]:
    """Histogram bin of every pixel in one pass (see engine.tracking.appearance.quantise).

    ``image`` is H x W x 1 (grey) or H x W x 3 (BGR), as for the other colour kernels.
    """
    h, w = image.shape[0], image.shape[1]
    out = np.empty((h, w), dtype=np.uint16)
    for i in range(h):
        for j in range(w):
            out[i, j] = pixel_bin(image, i, j, grey_bits, colour_bits)
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def colour_lookup(
    image: NDArray[np.uint8], grey_bits: int, colour_bits: int, table: NDArray[np.float32]
) -> NDArray[np.float32]:
    """``table[bin]`` of every pixel in one pass (p(object) per pixel)."""
    h, w = image.shape[0], image.shape[1]
    out = np.empty((h, w), dtype=np.float32)
    for i in range(h):
        for j in range(w):
            out[i, j] = table[pixel_bin(image, i, j, grey_bits, colour_bits)]
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def taught_counts(
    image: NDArray[np.uint8],
    grey_bits: int,
    colour_bits: int,
    mask: NDArray[np.uint8],
    inner: NDArray[np.uint8],
    outer: NDArray[np.uint8],
    table: NDArray[np.float32],
    above: np.float32,
    below: np.float32,
    bins: int,
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Colour-bin counts of the object's pixels and of its ring's, in one pass.

    The object's are the ``inner`` pixels (non-zero) whose ``table[bin]`` is
    above ``above``; the ring's are the ``outer`` pixels outside ``mask`` whose
    ``table[bin]`` is below ``below``.  An empty ``table`` takes every such pixel.
    The thresholds are float32, compared as numpy compares a float32 array with
    a Python float.  (See :func:`engine.tracking.appearance.Histograms.updated`.)
    """
    h, w = image.shape[0], image.shape[1]
    obj = np.zeros(bins, dtype=np.int64)
    ring = np.zeros(bins, dtype=np.int64)
    check = table.shape[0] > 0
    for i in range(h):
        for j in range(w):
            if inner[i, j]:
                b = pixel_bin(image, i, j, grey_bits, colour_bits)
                if not check or table[b] > above:
                    obj[b] += 1
            elif outer[i, j] and not mask[i, j]:
                b = pixel_bin(image, i, j, grey_bits, colour_bits)
                if not check or table[b] < below:
                    ring[b] += 1
    return obj, ring


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _reflect101(k: int, n: int) -> int:
    """OpenCV's default border (``gfedcb|abcdefgh|gfedcba``) for one step outside."""
    if n == 1:
        return 0
    if k < 0:
        return -k
    if k >= n:
        return 2 * n - 2 - k
    return k


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sobel_at(
    s: NDArray[np.float32], up: int, i: int, down: int, left: int, j: int, right: int
) -> float:
    gx = (s[up, right] + 2.0 * s[i, right] + s[down, right]) - (
        s[up, left] + 2.0 * s[i, left] + s[down, left]
    )
    gy = (s[down, left] + 2.0 * s[down, j] + s[down, right]) - (
        s[up, left] + 2.0 * s[up, j] + s[up, right]
    )
    return math.sqrt(gx * gx + gy * gy)


@nb.njit(cache=True, nogil=True, error_model="numpy", fastmath=True)
def sobel_magnitude(smooth: NDArray[np.float32]) -> NDArray[np.float32]:
    """|gradient| by the 3 x 3 Sobel operator (as ``cv2.Sobel`` + ``cv2.magnitude``,
    with OpenCV's default reflect-101 border)."""
    h, w = smooth.shape
    out = np.empty((h, w), dtype=np.float32)
    for i in range(h):
        up = _reflect101(i - 1, h)
        down = _reflect101(i + 1, h)
        out[i, 0] = _sobel_at(smooth, up, i, down, _reflect101(-1, w), 0, _reflect101(1, w))
        for j in range(1, w - 1):  # the interior: no border logic, vectorised
            out[i, j] = _sobel_at(smooth, up, i, down, j - 1, j, j + 1)
        if w > 1:
            out[i, w - 1] = _sobel_at(smooth, up, i, down, w - 2, w - 1, _reflect101(w, w))
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def scale_and_clip(image: NDArray[np.float32], factor: float) -> None:
    """``image = min(image * factor, 1)`` in place."""
    f = np.float32(factor)
    one = np.float32(1.0)
    h, w = image.shape
    for i in range(h):
        for j in range(w):
            image[i, j] = min(image[i, j] * f, one)


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _texel(image: NDArray[np.uint8], x: int, y: int) -> float:
    """``image[y, x]``, or 128 outside (``cv2.BORDER_CONSTANT``)."""
    if 0 <= x < image.shape[1] and 0 <= y < image.shape[0]:
        return float(image[y, x])
    return 128.0


@nb.njit(cache=True, nogil=True, error_model="numpy")
def occluded(
    prob: NDArray[np.float32],
    inside: NDArray[np.uint8],
    was: NDArray[np.uint8],
    warp: NDArray[np.float64],
    low: float,
    high: int,
) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    """Pixels that were the object's and now look like background.

    A pixel is covered when it is ``inside`` (non-zero), its ``prob`` is below
    ``low`` and the previous p(object) (``was``, 0-255) at the place the
    2 x 3 ``warp`` maps it to, bilinear with 128 outside, rounds above
    ``high`` (>= 128: pixels that map wholly outside ``was`` are never
    covered).  Returns the covered pixels' flat indices and their previous
    p(object) in [0, 1].
    """
    h, w = prob.shape
    where = np.empty(h * w, dtype=np.int64)  # pages are only touched if used
    value = np.empty(h * w, dtype=np.float32)
    count = 0
    a, b, c = warp[0, 0], warp[0, 1], warp[0, 2]
    d, e, f = warp[1, 0], warp[1, 1], warp[1, 2]
    limit_x = was.shape[1] + 1.0
    limit_y = was.shape[0] + 1.0
    last_x = was.shape[1] - 1
    last_y = was.shape[0] - 1
    for i in range(h):
        for j in range(w):
            if inside[i, j] == 0 or not prob[i, j] < low:
                continue
            x = a * j + b * i + c
            y = d * j + e * i + f
            if not (-1.0 < x < limit_x and -1.0 < y < limit_y):
                continue  # every neighbour is outside: 128, not covered
            x0 = math.floor(x)
            y0 = math.floor(y)
            fx = x - x0
            fy = y - y0
            if 0 <= x0 < last_x and 0 <= y0 < last_y:  # all four neighbours inside
                p00 = float(was[y0, x0])
                p01 = float(was[y0, x0 + 1])
                p10 = float(was[y0 + 1, x0])
                p11 = float(was[y0 + 1, x0 + 1])
            else:
                p00 = _texel(was, x0, y0)
                p01 = _texel(was, x0 + 1, y0)
                p10 = _texel(was, x0, y0 + 1)
                p11 = _texel(was, x0 + 1, y0 + 1)
            top = p00 + fx * (p01 - p00)
            bottom = p10 + fx * (p11 - p10)
            level = math.floor(top + fy * (bottom - top) + 0.5)
            if level > high:
                where[count] = i * w + j
                value[count] = level / 255.0
                count += 1
    return where[:count].copy(), value[:count].copy()


@nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def boundary_search(
    prob: NDArray[np.float32],
    edges: NDArray[np.float32],
    edge_step: int,
    nodes: NDArray[np.float64],
    normals: NDArray[np.float64],
    radius: int,
    region_weight: float,
    edge_weight: float,
    distance_penalty: float,
    offset: NDArray[np.float64],
    strength: NDArray[np.float64],
    relative: NDArray[np.float64],
) -> float:
    """Per-node best object-to-background split along the normal (engine.tracking.boundary).

    ``nodes`` are in the maps' pixel coordinates; ``edges`` has one pixel
    per ``edge_step`` (1 or 2) of them (see ``Maps.edge_step``).  Fills
    ``offset`` and ``strength``; returns the mean inside-minus-outside
    probability.  ``relative[n]`` in [0, 1] is how far node n compares the two
    sides with each other rather than each with 1/2 (1: a profile that is
    object-like all along gives no pull; see engine.tracking.holding).
    """
    # edge pixel u covers map pixels step u .. step u + step - 1
    to_edge = 1.0 / edge_step
    edge_shift = 0.5 / edge_step - 0.5
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
            e[j] = _bilinear(edges, x * to_edge + edge_shift, y * to_edge + edge_shift)
            q[j] = p - 0.5
            total += q[j]
            if j <= radius:
                inside += p
            if j >= radius:
                outside += p
        contrast += (inside - outside) / (radius + 1)
        if relative[n] > 0.0:
            level = relative[n] * total / k
            total -= level * k
            for j in range(k):
                q[j] -= level
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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def contour_pull(
    prob: NDArray[np.float32],
    edges: NDArray[np.float32],
    edge_step: int,
    nodes: NDArray[np.float64],
    radius: int,
    region_weight: float,
    edge_weight: float,
    distance_penalty: float,
    pull: NDArray[np.float64],
    relative: NDArray[np.float64],
) -> float:
    """:func:`boundary_search` along the outward normals, as pulls ``strength * offset * normal``.

    Fills ``pull`` (N, 2); returns the contrast.
    """
    n = nodes.shape[0]
    normals = outward_normals(nodes)
    offset = np.empty(n)
    strength = np.empty(n)
    contrast = boundary_search(
        prob,
        edges,
        edge_step,
        nodes,
        normals,
        radius,
        region_weight,
        edge_weight,
        distance_penalty,
        offset,
        strength,
        relative,
    )
    for i in range(n):
        pull[i, 0] = strength[i] * offset[i] * normals[i, 0]
        pull[i, 1] = strength[i] * offset[i] * normals[i, 1]
    return contrast


@nb.njit(cache=True, nogil=True, error_model="numpy")
def contrast_odds(
    r_o: NDArray[np.float32], r_b: NDArray[np.float32], noise: float, gain: float
) -> NDArray[np.float32]:
    """``gain (r_b - r_o) / (r_b + r_o + noise)`` per pixel, in float32 throughout.

    One pass over the two residual maps of :func:`engine.tracking.motion_contrast.motion_ratio`
    instead of four temporaries; each operation is rounded to float32 as numpy's and
    OpenCV's element-wise ones are, so the result is theirs bit for bit.
    """
    h, w = r_o.shape
    out = np.empty((h, w), dtype=np.float32)
    n = np.float32(noise)
    g = np.float32(gain)
    for i in range(h):
        for j in range(w):
            out[i, j] = g * (r_b[i, j] - r_o[i, j]) / (r_b[i, j] + r_o[i, j] + n)
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def scale_odds(probability: NDArray[np.float32], ratio: NDArray[np.float32]) -> NDArray[np.float32]:
    """``p r / (p r + 1 - p)`` per pixel: the odds of p(object) ``p`` times ``r``."""
    h, w = probability.shape
    out = np.empty((h, w), dtype=np.float32)
    for i in range(h):
        for j in range(w):
            p = probability[i, j]
            scaled = p * ratio[i, j]
            out[i, j] = scaled / (scaled + (1.0 - p))
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def side_contrast(
    probability: NDArray[np.float32],
    origin_x: float,
    origin_y: float,
    nodes: NDArray[np.float64],
    depth: int,
) -> NDArray[np.float64]:
    """Mean p(object) over 1..depth pixels inside each node minus outside it
    (see :func:`engine.tracking.holding.side_contrast`; nearest pixels, 1/2 outside)."""
    normals = outward_normals(nodes)
    h, w = probability.shape
    out = np.empty(nodes.shape[0])
    for k in range(nodes.shape[0]):
        x, y = nodes[k, 0] - origin_x, nodes[k, 1] - origin_y
        nx, ny = normals[k, 0], normals[k, 1]
        inside, outside = 0.0, 0.0
        for sign in (-1.0, 1.0):
            total = 0.0
            for step in range(1, depth + 1):
                j = int(np.rint(x + sign * step * nx))
                i = int(np.rint(y + sign * step * ny))
                if 0 <= j < w and 0 <= i < h:
                    total += float(probability[i, j])
                else:
                    total += 0.5
            if sign < 0:
                inside = total / depth
            else:
                outside = total / depth
        out[k] = inside - outside
    return out
