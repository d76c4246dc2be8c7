"""Holding the shape where the image says nothing: per-node boundary evidence, remembered.

The region cue pulls a node towards the object-to-background split along its
normal, judging each pixel against p(object) = 1/2; where the background next
to the object has the object's very colour (camouflage, a shadow of the
same tone), everything along the normal looks like object and the node is
pulled outward, into the background, frame after frame.  A node that had no
colour step across the contour on the first frame (where the contour is
given, so known to be right) is marked: its region cue compares the two sides
of each candidate split with each other instead (the profile's mean is taken
off), which gives no pull along a profile without a step, so the chain holds
it on the predicted shape; a real step within reach still pulls it.  The
marks ride with the contour from frame to frame (nearest node).  Coordinates
are ``[x, y]`` pixels (x = column, y = row).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.geometry import nearest

__all__ = ["DEPTH", "carry", "carry_by_shape", "hold_factors", "side_contrast"]

DEPTH = 6
"""Pixels sampled on each side of a node: beyond the contour's own mixed
pixels, within the object's and the background's near surroundings."""


def side_contrast(
    probability: NDArray[np.float32], origin: tuple[int, int], nodes: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Mean p(object) over 1..:data:`DEPTH` pixels inside each node minus outside it.

    ``probability`` covers the region whose top-left pixel is frame point
    ``origin``; samples (the nearest pixel along the node's outward normal,
    halves to even) outside it count as 1/2.  One compiled pass.
    """
    from engine.tracking._image_kernels import side_contrast as contrast

    x, y = origin
    result: NDArray[np.float64] = contrast(
        np.ascontiguousarray(probability, dtype=np.float32),
        float(x),
        float(y),
        np.ascontiguousarray(nodes, dtype=np.float64),
        DEPTH,
    )
    return result


def hold_factors(contrast: NDArray[np.float64], below: float) -> NDArray[np.float64]:
    """1 where the side contrast is 0 or less, falling linearly to 0 at ``below`` (0: none held)."""
    if below <= 0:
        return np.zeros(len(contrast))
    return np.clip(1.0 - contrast / below, 0.0, 1.0)


def carry(
    values: NDArray[np.float64], source: NDArray[np.float64], target: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Per-node ``values`` of contour ``source`` moved to the nearest node of ``target``."""
    if len(values) != len(source):
        return np.zeros(len(target))
    if target is source or np.array_equal(target, source):
        return values.copy()
    moved: NDArray[np.float64] = values[nearest(target, source)]
    return moved


def carry_by_shape(
    values: NDArray[np.float64], source: NDArray[np.float64], target: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`carry` from ``source`` to a ``target`` found elsewhere in the frame (a
    re-acquired contour): nodes matched by their place on the shape, both contours taken
    about their own centres."""
    return carry(values, source - source.mean(axis=0), target - target.mean(axis=0))
