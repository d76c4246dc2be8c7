"""Small seeded synthetic scenes for the tracker-component tests.

Frames are H x W x 3 BGR ``uint8``; points are ``[x, y]`` pixels (x = column,
y = row, a pixel's centre has integer coordinates); masks are H x W ``uint8``
(0 background, 255 object) filled by :func:`engine.geometry.contour_to_mask`.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask

U8 = NDArray[np.uint8]
F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

BACKGROUND_BGR = (60.0, 150.0, 70.0)  # greenish
OBJECT_BGR = (50.0, 60.0, 200.0)  # reddish


def texture(seed: int, height: int, width: int, cell: int = 4) -> F32:
    """Smooth random texture in [-0.5, 0.5]^3: noise on a ``cell``-pixel grid, cubic-upsampled."""
    rng = np.random.default_rng(seed)
    small = rng.uniform(-0.5, 0.5, (height // cell + 3, width // cell + 3, 3)).astype(np.float32)
    size = (small.shape[1] * cell, small.shape[0] * cell)
    big = np.asarray(cv2.resize(small, size, interpolation=cv2.INTER_CUBIC), dtype=np.float32)
    return np.ascontiguousarray(big[cell : cell + height, cell : cell + width])


def textured_frame(seed: int, height: int, width: int, amplitude: float = 120.0) -> U8:
    """A grey-ish textured BGR frame with plenty of corners."""
    img = 128.0 + amplitude * texture(seed, height, width)
    return np.asarray(np.clip(img, 0, 255).astype(np.uint8), dtype=np.uint8)


def disc_mask(center: tuple[float, float], radius: float, shape: tuple[int, int]) -> U8:
    """The true disc: pixel centres inside a 720-gon of the circle."""
    return contour_to_mask(circle_nodes(center, radius, 720), shape)


class DiscScene:
    """A textured reddish disc on a textured greenish background.

    The disc's own texture moves with it, so both the motion prediction and
    the colour model have something to work with.

    Parameters
    ----------
    width, height : int
        Frame size.
    radius : float
        Disc radius (pixels).
    seed : int
        Seed of both textures.
    """

    def __init__(self, width: int = 160, height: int = 120, radius: float = 22.0, seed: int = 0):
        self.width, self.height, self.radius = width, height, radius
        self._bg = np.asarray(BACKGROUND_BGR, np.float32) + 90.0 * texture(seed, height, width)
        side = int(2 * radius + 16)
        self._obj = np.asarray(OBJECT_BGR, np.float32) + 90.0 * texture(seed + 1, side, side)
        self._half = side / 2.0

    @property
    def shape(self) -> tuple[int, int]:
        """``(height, width)``."""
        return self.height, self.width

    def mask(self, center: tuple[float, float]) -> U8:
        """Ground-truth mask of the disc centred at ``center``."""
        return disc_mask(center, self.radius, self.shape)

    def frame(self, center: tuple[float, float]) -> U8:
        """The frame with the disc centred at ``center`` (sub-pixel placement)."""
        cx, cy = center
        shift = np.array([[1.0, 0.0, cx - self._half], [0.0, 1.0, cy - self._half]])
        obj = cv2.warpAffine(
            self._obj,
            shift,
            (self.width, self.height),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REFLECT,
        )
        inside = self.mask(center) > 0
        img = self._bg.copy()
        img[inside] = np.asarray(obj, np.float32)[inside]
        return np.asarray(np.clip(img, 0, 255).astype(np.uint8), dtype=np.uint8)


def two_colour_frame(
    center: tuple[float, float],
    radius: float,
    shape: tuple[int, int] = (120, 160),
    *,
    inside_bgr: tuple[int, int, int] = (40, 40, 200),
    outside_bgr: tuple[int, int, int] = (200, 160, 40),
    noise: float = 6.0,
    seed: int = 0,
) -> U8:
    """A flat-coloured disc on a flat background, with mild Gaussian noise."""
    rng = np.random.default_rng(seed)
    img = np.empty((*shape, 3), np.float64)
    img[:] = outside_bgr
    img[disc_mask(center, radius, shape) > 0] = inside_bgr
    img += rng.normal(0.0, noise, img.shape)
    return np.asarray(np.clip(img, 0, 255).astype(np.uint8), dtype=np.uint8)


def centroid(mask: U8) -> F64:
    """``[x, y]`` centroid of a mask's object pixels."""
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()], dtype=np.float64)


def shifted(image: U8, dx: float, dy: float) -> U8:
    """``image`` translated by ``(dx, dy)`` pixels, bilinear, the border reflected."""
    h, w = image.shape[:2]
    matrix = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]])
    return np.asarray(
        cv2.warpAffine(
            image, matrix, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
        ),
        np.uint8,
    )


def decoy_scene(
    moved: tuple[float, float] = (6.0, 3.0),
) -> tuple[U8, U8, U8, NDArray[np.bool_]]:
    """A textured disc whose box holds a still patch of its colours, on a background
    that is itself mostly of its colours: frame, next frame, truth, the patch.

    Colour alone keeps the patch (as GrabCut kept a hockey fence, a wall behind a
    dancer); only the disc moves (by ``moved``) between the two frames.
    """
    scene = DiscScene(width=240, height=180, radius=40.0, seed=5)
    start = (120.0, 90.0)
    after = (start[0] + moved[0], start[1] + moved[1])
    share = 0.7  # of the object's colour in the background's
    base = (1 - share) * np.asarray(BACKGROUND_BGR, np.float32) + share * np.asarray(
        OBJECT_BGR, np.float32
    )
    background: U8 = np.clip(base + 90.0 * texture(11, 180, 240), 0, 255).astype(np.uint8)
    colours = np.asarray(OBJECT_BGR, np.float32) + 90.0 * texture(12, 180, 240)
    patch_colours = np.clip(colours, 0, 255).astype(np.uint8)
    patch = np.zeros((180, 240), np.bool_)
    patch[50:85, 80:115] = True  # the box's top-left corner
    patch &= (scene.mask(start) == 0) & (scene.mask(after) == 0)

    def frame(centre: tuple[float, float]) -> U8:
        disc, inside = scene.frame(centre), scene.mask(centre) > 0
        out: U8 = background.copy()
        out[patch] = patch_colours[patch]
        out[inside] = disc[inside]
        return out

    return frame(start), frame(after), scene.mask(start), patch


def body_with_legs(
    shape: tuple[int, int],
    body: tuple[float, float],
    hip: tuple[int, int],
    legs: list[list[float]],
    *,
    length: float,
    width: int,
) -> tuple[list[U8], list[U8]]:
    """Frames and masks of a still disc (radius 30) with legs swinging from ``hip``.

    ``legs[k]`` holds frame ``k``'s leg angles in degrees (0: straight down, positive:
    towards +x); each leg is a line ``length`` px long and ``width`` px thick.  The
    object is orange on dark blue, flat (no noise): the colours alone tell them apart.
    """
    frames, masks = [], []
    for angles in legs:
        mask = contour_to_mask(circle_nodes(body, 30.0, 360), shape)
        for angle in np.deg2rad(angles):
            tip = (hip[0] + length * np.sin(angle), hip[1] + length * np.cos(angle))
            cv2.line(mask, hip, (round(tip[0]), round(tip[1])), 255, width)
        image = np.where(mask[..., None] > 0, [50, 170, 230], [110, 70, 40]).astype(np.uint8)
        frames.append(image)
        masks.append(mask)
    return frames, masks
