"""The tracker's guard: is a contour plausible as the object's next outline?

Every contour the tracker takes from a stage (a prediction, a refinement)
passes this check first; an implausible one is replaced by the last
plausible contour.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.geometry import extent, polygon_area, self_intersects

__all__ = ["valid_contour"]

MIN_AREA_RATIO = 0.2
"""A contour enclosing less than a fifth of the last one's area has collapsed:
no object shrinks by 5x between two frames of a video."""
MAX_AREA_RATIO = 25.0
"""Nor grows by 25x in area (5x across)."""
MAX_EXTENT = 4
"""A contour wider than four times the frame's larger side has exploded."""


def valid_contour(
    nodes: NDArray[np.float64],
    shape: tuple[int, ...],
    reference: NDArray[np.float64],
    *,
    check_crossing: bool = True,
) -> bool:
    """Finite, not collapsed, not exploded and (optionally) not self-crossing.

    Parameters
    ----------
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, the contour to check.
    shape : tuple of int
        Shape of the frame (height first).
    reference : numpy.ndarray
        (M, 2) ``[x, y]`` pixels, the last accepted contour: ``nodes`` must
        enclose between :data:`MIN_AREA_RATIO` and :data:`MAX_AREA_RATIO`
        times its area.
    check_crossing : bool
        Also reject a self-intersecting contour.

    Returns
    -------
    bool
    """
    if not np.isfinite(nodes).all():
        return False
    area = abs(polygon_area(nodes))
    ref = abs(polygon_area(reference))
    x0, y0, x1, y1 = extent(nodes)
    if not MIN_AREA_RATIO * ref <= area <= MAX_AREA_RATIO * ref:
        return False
    if max(x1 - x0, y1 - y0) > MAX_EXTENT * max(shape):
        return False
    return not (check_crossing and self_intersects(nodes))
