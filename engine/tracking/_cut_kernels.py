"""Compiled loops (numba) of the band segmentation: local colour windows and the band graph.

Imported lazily, like :mod:`engine.tracking._image_kernels`.  Images are
indexed ``[y, x]``; window centres are ``[x, y]`` pixels of the same region.
Kernels use numba's ``error_model="numpy"``: no zero-division check in the
loops, so they vectorise (every divisor is non-zero by construction; the
results are bit for bit those of the default model).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from engine.tracking._image_kernels import pixel_bin

PROBABILITY_FLOOR = 1e-3
"""p(object) is clipped to [1e-3, 1 - 1e-3]: a colour never seen on one side
costs at most log(999) ~ 7 in the cut, not infinity."""
SHAPE_CLIP = 6.0
"""The shape prior's log-odds saturate at 6 (p ~ 0.998): beyond that the band's
fixed pixels, not the prior, hold the object."""
UNSEEN = 0.01
"""Pseudo-count per bin of a window's histograms, so that a colour the window
never saw has equal (small) likelihood on both sides."""
COVERED = 0.3
"""Summed window weight at which a pixel counts as fully covered by local models;
less coverage blends in the global model."""


@nb.njit(cache=True, nogil=True, error_model="numpy")
def learn_windows(
    image: NDArray[np.uint8],
    grey_bits: int,
    colour_bits: int,
    inside: NDArray[np.uint8],
    outside: NDArray[np.uint8],
    centres: NDArray[np.int64],
    half: int,
    nbins: int,
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Object and background colour counts of square windows.

    ``image``: H x W x C (C = 1 grey, 3 BGR), binned at ``grey_bits`` /
    ``colour_bits`` as :func:`engine.tracking._image_kernels.colour_bins` does,
    but only where a window counts a pixel (the windows cover the contour's
    band, not the box's interior); ``inside``/``outside``: 1 where a pixel is
    surely object / surely background; ``centres``: (K, 2) ``[x, y]`` window
    centres; ``half``: half the window's side.  Returns (K, nbins) counts.
    """
    h, w = inside.shape
    k = centres.shape[0]
    fg = np.zeros((k, nbins), dtype=np.float32)
    bg = np.zeros((k, nbins), dtype=np.float32)
    for n in range(k):
        cx, cy = centres[n, 0], centres[n, 1]
        for y in range(max(cy - half, 0), min(cy + half + 1, h)):
            for x in range(max(cx - half, 0), min(cx + half + 1, w)):
                if inside[y, x]:
                    fg[n, pixel_bin(image, y, x, grey_bits, colour_bits)] += 1.0
                elif outside[y, x]:
                    bg[n, pixel_bin(image, y, x, grey_bits, colour_bits)] += 1.0
    return fg, bg


@nb.njit(cache=True, nogil=True, error_model="numpy")
def local_probability(
    image: NDArray[np.uint8],
    grey_bits: int,
    colour_bits: int,
    wanted: NDArray[np.uint8],
    centres: NDArray[np.int64],
    half: int,
    fg: NDArray[np.float32],
    bg: NDArray[np.float32],
    trust: float,
    min_count: float,
    fallback: NDArray[np.float32],
) -> NDArray[np.float32]:
    """p(object) from the windows' models, blended where windows overlap.

    Each window k gives p_k = P_k(c | object) / (P_k(c | object) + P_k(c |
    background)) from its own counts, trusted in proportion to how often it
    saw the colour (``trust`` sightings: fully); ``fallback`` (the global
    model's p) fills in the rest.  Windows are weighted by a Gaussian of the
    distance to their centre.  Only pixels where ``wanted`` is set are
    computed; the others keep ``fallback``.  ``image`` is binned as for
    :func:`learn_windows`, where a window needs a pixel.
    """
    h, w = wanted.shape
    nb_ = fg.shape[1]
    num = np.zeros((h, w), dtype=np.float32)
    den = np.zeros((h, w), dtype=np.float32)
    spread = 2.0 * (0.6 * half) ** 2
    # the Gaussian weight of each offset from a window's centre, once for all windows
    side = 2 * half + 1
    gauss = np.empty((side, side))
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            gauss[dy + half, dx + half] = math.exp(-(dx**2 + dy**2) / spread)
    for n in range(centres.shape[0]):
        nf = 0.0
        nbg = 0.0
        for b in range(nb_):
            nf += fg[n, b]
            nbg += bg[n, b]
        if nf < min_count or nbg < min_count:
            continue
        zf = nf + UNSEEN * nb_
        zb = nbg + UNSEEN * nb_
        cx, cy = centres[n, 0], centres[n, 1]
        for y in range(max(cy - half, 0), min(cy + half + 1, h)):
            for x in range(max(cx - half, 0), min(cx + half + 1, w)):
                if not wanted[y, x]:
                    continue
                c = pixel_bin(image, y, x, grey_bits, colour_bits)
                pf = (fg[n, c] + UNSEEN) / zf
                pb = (bg[n, c] + UNSEEN) / zb
                seen = min((fg[n, c] + bg[n, c]) / trust, 1.0)
                p = seen * pf / (pf + pb) + (1.0 - seen) * fallback[y, x]
                weight = gauss[y - cy + half, x - cx + half]
                num[y, x] += weight * p
                den[y, x] += weight
    out = fallback.copy()
    for y in range(h):
        for x in range(w):
            if den[y, x] > 0.0:
                cover = min(den[y, x] / COVERED, 1.0)
                out[y, x] = cover * num[y, x] / den[y, x] + (1.0 - cover) * fallback[y, x]
    return out


@nb.njit(cache=True, nogil=True, inline="always")
def _step(image: NDArray[np.uint8], y: int, x: int, yy: int, xx: int) -> float:
    """Squared colour difference of two pixels."""
    diff = 0.0
    for c in range(image.shape[2]):
        t = float(image[y, x, c]) - float(image[yy, xx, c])
        diff += t * t
    return diff


@nb.njit(cache=True, nogil=True, error_model="numpy")
def band_graph(
    distance: NDArray[np.float32],
    band: float,
    image: NDArray[np.uint8],
    probability: NDArray[np.float32],
    weights: NDArray[np.float64],
) -> tuple[
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int32],
    NDArray[np.float64],
]:
    """The graph of the band's pixels for a binary cut (object = source side).

    ``distance``: signed distance (pixels, > 0 inside) to the prior contour;
    pixels with ``|distance| <= band`` are free, the others keep their side
    and pass their links to the free neighbours as terminal weights.
    ``weights`` = (colour, shape, smoothness, shape scale): the unary term is
    ``colour * logit(p) + shape * clip(distance / scale)`` and each 4-neighbour
    link costs ``smoothness * exp(-|dI|^2 / (2 mean |dI|^2))`` (contrast-
    sensitive Potts, as in GrabCut).

    Returns the flat indices of the free pixels, their source and sink
    capacities, and for each its free neighbours to the right, below, left and
    above (their indices, -1 for none) and the capacities of those links.
    """
    h, w = distance.shape
    colour, shape, smooth, scale = weights[0], weights[1], weights[2], weights[3]
    # the free pixels in row-major order; a vectorised test, not a branch per pixel of
    # the region (most of a large object's region is its fixed interior)
    pixels = np.flatnonzero(np.abs(distance) <= band).astype(np.int64)
    count = len(pixels)
    index = np.full(h * w, -1, dtype=np.int32)
    for k in range(count):
        index[pixels[k]] = k
    source = np.empty(count, dtype=np.float64)
    sink = np.empty(count, dtype=np.float64)
    # each pixel's squared colour step to its right and lower neighbours (-1: none),
    # computed once for the mean contrast and again used for the links
    steps = np.full((count, 2), -1.0)
    total = 0.0
    links = 0
    for k in range(count):
        y, x = pixels[k] // w, pixels[k] % w
        p = min(max(probability[y, x], PROBABILITY_FLOOR), 1.0 - PROBABILITY_FLOOR)
        d = min(max(distance[y, x] / scale, -SHAPE_CLIP), SHAPE_CLIP)
        u = colour * math.log(p / (1.0 - p)) + shape * d
        source[k] = max(u, 0.0)
        sink[k] = max(-u, 0.0)
        for n, (dy, dx) in enumerate(((0, 1), (1, 0))):
            if y + dy < h and x + dx < w:
                steps[k, n] = _step(image, y, x, y + dy, x + dx)
                total += steps[k, n]
                links += 1
    contrast = 1.0 / (2.0 * max(total / max(links, 1), 1e-6))
    neighbours = np.full((count, 4), -1, dtype=np.int32)
    capacities = np.zeros((count, 4), dtype=np.float64)
    for k in range(count):
        y, x = pixels[k] // w, pixels[k] % w
        for n, (dy, dx) in enumerate(((0, 1), (1, 0), (0, -1), (-1, 0))):
            yy, xx = y + dy, x + dx
            if yy < 0 or yy >= h or xx < 0 or xx >= w:
                continue
            other = index[yy * w + xx]
            if other >= 0 and n >= 2:
                continue  # each free-free link once, from its upper-left end
            diff = steps[k, n] if n < 2 else _step(image, y, x, yy, xx)
            cost = smooth * math.exp(-contrast * diff)
            if other >= 0:  # and the same link seen from the other end
                neighbours[k, n], capacities[k, n] = other, cost
                neighbours[other, n + 2], capacities[other, n + 2] = k, cost
            elif distance[yy, xx] > 0:
                source[k] += cost
            else:
                sink[k] += cost
    return pixels, source, sink, neighbours, capacities


@nb.njit(cache=True, nogil=True, error_model="numpy")
def settle(
    source: NDArray[np.float64],
    sink: NDArray[np.float64],
    neighbours: NDArray[np.int32],
    capacities: NDArray[np.float64],
) -> tuple[
    NDArray[np.int8],
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.float64],
    NDArray[np.int32],
    NDArray[np.int32],
    NDArray[np.float64],
]:
    """The nodes whose side every minimum cut agrees on, and the graph left for the others.

    A node whose terminal capacities differ by more than the summed capacity of its
    links is on its stronger terminal's side in every minimum cut: moving it across
    would cut more than it could uncut.  Once settled, its links to unsettled nodes
    become their terminal capacities, which may settle them in turn; a node's margin
    never shrinks as its neighbours settle, so the settled set does not depend on the
    order.  On the cut's thin bands half the pixels or more settle, and the maximum
    flow on the rest costs a fifth of the whole (the labels are the same).

    ``neighbours`` and ``capacities`` are :func:`band_graph`'s.  Returns each node's
    side (1 source, -1 sink, 0 unsettled), the unsettled nodes, their source and sink
    capacities, and the links between them (i, j among the unsettled nodes, capacity;
    each once, in :func:`band_graph`'s order).
    """
    n = len(source)
    src = source.copy()
    snk = sink.copy()
    side = np.zeros(n, dtype=np.int8)
    queued = np.ones(n, dtype=np.bool_)
    stack = np.arange(n - 1, -1, -1).astype(np.int64)
    top = n
    while top > 0:
        top -= 1
        k = stack[top]
        queued[k] = False
        if side[k] != 0:
            continue
        links = 0.0
        for e in range(4):
            o = neighbours[k, e]
            if o >= 0 and side[o] == 0:
                links += capacities[k, e]
        if src[k] - snk[k] > links:
            side[k] = 1
        elif snk[k] - src[k] > links:
            side[k] = -1
        else:
            continue
        for e in range(4):
            o = neighbours[k, e]
            if o < 0 or side[o] != 0:
                continue
            if side[k] > 0:
                src[o] += capacities[k, e]
            else:
                snk[o] += capacities[k, e]
            if not queued[o]:
                queued[o] = True
                stack[top] = o
                top += 1
    free = np.flatnonzero(side == 0)
    renumber = np.full(n, -1, dtype=np.int32)
    for f in range(len(free)):
        renumber[free[f]] = f
    li = np.empty(2 * len(free), dtype=np.int32)
    lj = np.empty(2 * len(free), dtype=np.int32)
    lw = np.empty(2 * len(free), dtype=np.float64)
    m = 0
    for k in free:
        for e in range(2):  # right and below: each link once
            o = neighbours[k, e]
            if o >= 0 and side[o] == 0:
                li[m], lj[m], lw[m] = renumber[k], renumber[o], capacities[k, e]
                m += 1
    return side, free, src[free], snk[free], li[:m], lj[:m], lw[:m]
