"""``TrackResult``: what :meth:`engine.tracking.Tracker.step` returns for a frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.tracking.confidence import Status

__all__ = ["TrackResult"]


@dataclass(frozen=True, slots=True)
class TrackResult:
    """Result of one :meth:`Tracker.step`.

    Attributes
    ----------
    nodes : numpy.ndarray
        (N, 2) float64 contour, ``[x, y]`` pixels.
    iterations : int
        Refinement iterations run.
    converged : bool
        Whether the refinement settled before the iteration limit.
    confidence : float
        In [0, 1]: the predicted overlap (IoU) of the contour with the object
        (:mod:`engine.tracking.confidence`); 0 for a contour outside the frame.
    status : {"tracking", "uncertain", "lost"}
        ``tracking``: the contour is on the object; ``uncertain``: it may be
        off; ``lost``: it most likely does not cover the object (from the
        confidence, :func:`engine.tracking.confidence.status_of`).
    """

    nodes: NDArray[np.float64]
    iterations: int
    converged: bool
    confidence: float
    status: Status = "tracking"
