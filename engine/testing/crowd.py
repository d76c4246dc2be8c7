"""A generated scene of several moving objects, some overlapping, with per-object masks.

Each object is an ellipse of its own colour with a texture that moves with
it, moving at constant speed (bouncing off the frame's edges) over a
textured background; objects are painted in a fixed depth order (the later
in front).  Pairs are launched towards each other so that some overlap for a
few frames.  Masks are amodal (each object's whole silhouette, also where
another covers it).  Coordinates are ``[x, y]`` pixels; frames H x W x 3 BGR
``uint8``; masks H x W ``uint8``, 0 or 255.  Deterministic for a given seed.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["Crowd", "make_crowd"]

U8 = NDArray[np.uint8]


@dataclass(frozen=True)
class Crowd:
    """The frames and, per object, its mask in every frame (``masks[k][t]``)."""

    frames: tuple[U8, ...]
    masks: tuple[tuple[U8, ...], ...]


def _texture(rng: np.random.Generator, h: int, w: int, amplitude: float) -> NDArray[np.float32]:
    noise = rng.normal(0.0, 1.0, (h // 4 + 1, w // 4 + 1)).astype(np.float32)
    big = cv2.resize(noise, (w, h), interpolation=cv2.INTER_CUBIC)
    return np.asarray(amplitude * big / max(float(np.abs(big).max()), 1e-6), np.float32)


def make_crowd(
    *, seed: int = 0, count: int = 8, length: int = 30, size: tuple[int, int] = (480, 640)
) -> Crowd:
    """``count`` objects over ``length`` frames of ``size`` (height, width)."""
    rng = np.random.default_rng(seed)
    h, w = size
    grey = np.asarray([170.0, 175.0, 165.0], np.float32)
    background = grey + _texture(rng, h, w, 25.0)[..., None]
    hues = np.linspace(0, 180, count, endpoint=False)
    axes = rng.uniform(24, 34, (count, 2))
    # one object per cell of a grid, so that they start apart
    cols = int(np.ceil(np.sqrt(count * w / h)))
    rows = int(np.ceil(count / cols))
    cell = np.array([w / cols, h / rows])
    grid = np.array([[(i % cols + 0.5), (i // cols + 0.5)] for i in range(count)]) * cell
    start = grid + rng.uniform(-0.15, 0.15, (count, 2)) * cell
    speed = rng.uniform(1.5, 3.5, count)
    heading = rng.uniform(0, 2 * np.pi, count)
    for a in range(0, count - 1, 4):  # every fourth pair of neighbours cross each other's way
        b = a + 1
        heading[a] = np.arctan2(*(start[b] - start[a])[::-1]) + 0.5
        heading[b] = np.arctan2(*(start[a] - start[b])[::-1]) - 0.5
    velocity = speed[:, None] * np.column_stack([np.cos(heading), np.sin(heading)])
    colours = []
    for hue in hues:
        hsv = np.array([[[hue, 200, 190]]], np.uint8)
        colours.append(cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0].astype(np.float32))
    skins = [_texture(rng, h, w, 30.0) for _ in range(count)]
    frames: list[U8] = []
    masks: list[list[U8]] = [[] for _ in range(count)]
    position = start.copy()
    lo, hi = start - 0.45 * cell, start + 0.45 * cell  # each stays near its cell, but pairs
    for k in range(0, count - 1, 4):  # the crossing pairs roam both their cells
        lo[k] = lo[k + 1] = np.minimum(lo[k], lo[k + 1])
        hi[k] = hi[k + 1] = np.maximum(hi[k], hi[k + 1])
    for _ in range(length):
        image = background.copy()
        for k in range(count):
            mask = np.zeros((h, w), np.uint8)
            centre = (round(position[k, 0] * 16), round(position[k, 1] * 16))
            half = (round(axes[k, 0] * 16), round(axes[k, 1] * 16))
            cv2.ellipse(mask, centre, half, 0.0, 0.0, 360.0, 255, -1, cv2.LINE_8, 4)
            masks[k].append(mask)
            # the skin moves with the object (a texture fixed in the frame would slide under
            # it, and a tracker reading the object's own motion would see it stand still)
            dx, dy = position[k] - start[k]
            shift = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]], np.float32)
            skin = np.asarray(
                cv2.warpAffine(skins[k], shift, (w, h), borderMode=cv2.BORDER_REFLECT), np.float32
            )
            image[mask > 0] = (colours[k] + skin[..., None])[mask > 0]
        frames.append(np.asarray(np.clip(image, 0, 255), np.uint8))
        position += velocity
        out = (position < lo + axes) | (position > hi - axes)  # bounce off the cell's walls
        velocity[out] *= -1
    return Crowd(tuple(frames), tuple(tuple(m) for m in masks))
