"""Occluders: pixels that were the object's and now look like background.

A pixel inside the object's rigidly moved silhouette whose object-attached
place in the previous frame was object-like, but which now looks like
background, is most likely covered by something passing in front: it
should neither pull the contour in nor count as the object's edge, and the
object goes on under it.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

from typing import TypeAlias

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask
from engine.tracking.maps import Maps

__all__ = ["LocatedProbability", "Silhouette", "unoccluded"]

LocatedProbability: TypeAlias = tuple[tuple[int, int], NDArray[np.uint8]]
"""p(object) as 0-255 over a region of a frame, with the region's ``(x, y)`` origin."""

Silhouette: TypeAlias = tuple[NDArray[np.float64], NDArray[np.float64]]
"""The object's 2 x 3 similarity motion and the previous contour moved by it, ``[x, y]``."""

BACKGROUND_BELOW = 0.35
"""A pixel looks like background now when p(object) < 0.35: clearly below the
0.5 of an unknown colour, so a merely ambiguous pixel is not taken for an occluder."""
OBJECT_ABOVE = 166
"""A pixel was the object's when its previous p(object) rounds above 166/255
(0.65): the mirror image of :data:`BACKGROUND_BELOW` around 0.5."""
RIM_SLACK = 3
"""Pixels of slack around the silhouette: the rigid motion misses the object's
own deformation by about that much between frames."""
NEUTRAL = 0.5
"""p(object) of a covered pixel during refinement: no pull either way."""


def unoccluded(
    maps: Maps, previous: LocatedProbability | None, silhouette: Silhouette
) -> tuple[Maps, Maps]:
    """Colour evidence with occluders made neutral (p = 0.5).

    Parameters
    ----------
    maps : Maps
        Cue maps of the current frame.
    previous : tuple, optional
        ``((x, y), p)``: p(object) as 0-255 around the contour in the
        previous frame and its origin; without it nothing is changed.
    silhouette : tuple of numpy.ndarray
        ``(motion, rest)``: the 2 x 3 similarity mapping ``[x, y, 1]`` of the
        previous frame to the current one, and the previous contour moved by
        it, (N, 2) ``[x, y]`` pixels.

    Returns
    -------
    refine : Maps
        ``maps`` with the covered pixels at p = 0.5, for the refinement
        (``observed`` keeps what the pixels look like).
    remember : Maps
        ``maps`` with the covered pixels at their previous p(object) (the
        object goes on under the occluder), for the next frame.
        Both are ``maps`` itself when no pixel is covered.
    """
    from engine.tracking._image_kernels import occluded

    if previous is None:
        return maps, maps
    motion, rest = silhouette
    (px, py), was_prob = previous
    ox, oy = maps.origin
    h, w = maps.probability.shape
    # current ROI pixel (u, v) -> frame (u + ox, v + oy) -> previous frame via
    # the inverse motion -> previous ROI (subtract (px, py))
    a = np.vstack([motion, [0.0, 0.0, 1.0]])
    inverse = np.linalg.inv(a)
    shift = np.array([[1.0, 0.0, ox], [0.0, 1.0, oy], [0.0, 0.0, 1.0]])
    back = np.array([[1.0, 0.0, -px], [0.0, 1.0, -py], [0.0, 0.0, 1.0]])
    m = np.ascontiguousarray((back @ inverse @ shift)[:2])
    near = np.ones((2 * RIM_SLACK + 1, 2 * RIM_SLACK + 1), np.uint8)
    inside = np.asarray(cv2.dilate(contour_to_mask(rest - [ox, oy], (h, w)), near), np.uint8)
    where, was = occluded(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        inside,
        np.ascontiguousarray(was_prob, dtype=np.uint8),
        m,
        BACKGROUND_BELOW,
        OBJECT_ABOVE,
    )
    if len(where) == 0:
        return maps, maps
    prob = maps.probability.copy()
    prob.reshape(-1)[where] = NEUTRAL  # a view of the copy: faster than .flat
    memory = maps.probability.copy()
    memory.reshape(-1)[where] = was
    return (
        Maps(maps.origin, prob, maps.edges, maps.edge_step, observed=maps.probability),
        Maps(maps.origin, memory, maps.edges, maps.edge_step),
    )
