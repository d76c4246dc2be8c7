"""Rasterising for :mod:`engine.testing.synthetic`: anti-aliased polygons, masks, backgrounds.

Points are ``[x, y]`` pixels; images are float32 H x W x 3 BGR while drawn.
"""

from __future__ import annotations

from functools import cache
from statistics import NormalDist

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["background", "blob", "coverage", "fill", "gauss_table", "paint", "paint_image"]

SS = 4
"""Supersampling factor for anti-aliased coverage (4 x 4 samples a pixel)."""

HALF = np.float32((SS * SS // 2) / (SS * SS))
"""Coverage from which a pixel is in a mask: half its samples (8 of 16) inside."""

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


@cache
def gauss_table() -> F32:
    """Standard normal quantiles of 65536 equiprobable bins: fast sensor noise via lookup."""
    nd = NormalDist()
    return np.array([nd.inv_cdf((i + 0.5) / 65536) for i in range(65536)], np.float32)


def coverage(polys: F64 | list[F64], H: int, W: int) -> tuple[int, int, F32] | None:
    """Anti-aliased area coverage of a polygon, or of the union of several:
    ``(y0, x0, alpha)`` over the clipped bbox."""
    parts = [polys] if isinstance(polys, np.ndarray) else polys
    poly = np.vstack(parts)
    x0, y0 = (max(int(np.floor(v)) - 1, 0) for v in poly.min(axis=0))
    x1, y1 = min(int(np.ceil(poly[:, 0].max())) + 2, W), min(int(np.ceil(poly[:, 1].max())) + 2, H)
    if x1 <= x0 or y1 <= y0:
        return None
    canvas = np.zeros(((y1 - y0) * SS, (x1 - x0) * SS), np.uint8)
    for part in parts:  # one by one: fillPoly fills overlaps of a list even-odd
        hi = (part - (x0, y0) + 0.5) * SS - 0.5  # supersampled pixel centres
        pts = np.round(np.clip(hi, -1e5, 1e5) * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.fillPoly(canvas, [pts], 255, lineType=cv2.LINE_8, shift=4)
    alpha = cv2.resize(canvas, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return y0, x0, alpha.astype(np.float32) / np.float32(255.0)


def paint(img: F32, poly: F64, colour: tuple[float, float, float] | F64) -> None:
    """Composite a flat-coloured anti-aliased polygon onto ``img`` in place."""
    cov = coverage(poly, img.shape[0], img.shape[1])
    if cov is not None:
        y0, x0, a = cov
        roi = img[y0 : y0 + a.shape[0], x0 : x0 + a.shape[1]]
        roi += a[..., None] * (np.asarray(colour, np.float32) - roi)


def paint_image(img: F32, poly: F64, source: F32) -> None:
    """Composite the pixels of ``source`` (same size as ``img``) inside a polygon, anti-aliased."""
    cov = coverage(poly, img.shape[0], img.shape[1])
    if cov is not None:
        y0, x0, a = cov
        h, w = a.shape
        roi = img[y0 : y0 + h, x0 : x0 + w]
        roi += a[..., None] * (source[y0 : y0 + h, x0 : x0 + w] - roi)


def fill(polys: list[F64], H: int, W: int) -> U8:
    """The mask (0 / 255) of the pixels the union of polygons covers at least half of.

    DAVIS's annotations follow this rule: a pixel is object when most of it is
    object in the (anti-aliased) frame, :data:`HALF` of its :func:`coverage`
    samples.  Filling the outline with :func:`engine.geometry.contour_to_mask`
    instead adds every pixel the outline touches: half a pixel more all round.
    """
    mask = np.zeros((H, W), np.uint8)
    cov = coverage(polys, H, W)
    if cov is not None:
        y0, x0, alpha = cov
        h, w = alpha.shape
        mask[y0 : y0 + h, x0 : x0 + w] = np.where(alpha >= HALF, 255, 0).astype(np.uint8)
    return mask


def blob(rng: np.random.Generator, center: F64, radius: float) -> F64:
    """A random static blob outline (for clutter)."""
    t = np.linspace(0.0, 2 * np.pi, 120, endpoint=False)
    r = radius * (
        1 + sum(rng.uniform(0, 0.15) * np.cos(k * t + rng.uniform(0, 6.3)) for k in (2, 3))
    )
    return np.asarray(np.c_[center[0] + r * np.cos(t), center[1] + r * np.sin(t)], np.float64)


def background(rng: np.random.Generator, H: int, W: int, base: F64, amp: float) -> F32:
    """Smooth two-colour gradient plus low-frequency blotches and fine grain (amplitude ``amp``)."""
    a = rng.uniform(0, 2 * np.pi)
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    g = (np.cos(a) * (xs - W / 2) + np.sin(a) * (ys - H / 2)) / np.float32(np.hypot(H, W) / 2)
    d = rng.normal(size=3) * amp / np.sqrt(3) + amp * 0.8
    coarse = rng.normal(size=(5, 7)).astype(np.float32)
    blotch = cv2.resize(coarse, (W, H), interpolation=cv2.INTER_CUBIC)
    grain = cv2.GaussianBlur(rng.normal(size=(H, W)).astype(np.float32), (0, 0), 0.8)
    img = base.astype(np.float32) + g[..., None] * d.astype(np.float32)
    img += (0.5 * amp * blotch + 0.3 * amp * grain)[..., None]
    return np.asarray(img, np.float32)
