"""``PiecesTracker``: one object seen as several separate pieces, each held by its own chain.

A kite and its surfer, a rider seen through branches: one object, several
closed outlines.  Each piece is followed by its own :class:`Tracker` (its own
chain, motion, colour models and search), so the physics holds each piece's
shape; the object's confidence is the pieces' confidences weighted by their
areas, and its status follows from it
(:func:`engine.tracking.confidence.status_of`).  Coordinates are ``[x, y]``
pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import polygon_area
from engine.tracking._frames import as_frame
from engine.tracking.confidence import Status, status_of
from engine.tracking.noise import Smoothing
from engine.tracking.result import TrackResult
from engine.tracking.shared import Crowd
from engine.tracking.tracker import Tracker
from engine.tracking.working import WorkingFrames

__all__ = ["PiecesResult", "PiecesTracker"]

KIND = "pieces"


@dataclass(frozen=True, slots=True)
class PiecesResult:
    """Result of one :meth:`PiecesTracker.step`.

    Attributes
    ----------
    contours : list of numpy.ndarray
        One (N_i, 2) float64 ``[x, y]`` contour per piece, in the order given.
    confidence : float
        In [0, 1]: the pieces' confidences weighted by their areas.
    status : {"tracking", "uncertain", "lost"}
        From ``confidence``.
    pieces : list of TrackResult
        Each piece's own result.
    """

    contours: list[NDArray[np.float64]]
    confidence: float
    status: Status
    pieces: list[TrackResult]

    @property
    def nodes(self) -> NDArray[np.float64]:
        """The first piece's contour (the largest, for :func:`mask_to_contours`' order)."""
        return self.contours[0]

    @property
    def iterations(self) -> int:
        """The most refinement iterations any piece ran."""
        return max(p.iterations for p in self.pieces)

    @property
    def converged(self) -> bool:
        """Whether every piece's refinement settled."""
        return all(p.converged for p in self.pieces)


class PiecesTracker:
    """Follows an object made of several separate pieces, one :class:`Tracker` each.

    Parameters
    ----------
    contours : sequence of array_like
        One closed contour per piece, (N_i, 2) ``[x, y]`` pixels, N_i >= 3
        (e.g. :func:`engine.geometry.mask_to_contours` of the object's mask).
    **options
        :class:`TrackerOptions` fields, the same for every piece.

    Raises
    ------
    ValueError
        On no piece, a malformed contour or an invalid option.
    """

    def __init__(self, contours: Sequence[ArrayLike], **options: Any) -> None:
        if len(contours) == 0:
            raise ValueError("an object needs at least one piece")
        self.trackers = [Tracker(c, **options) for c in contours]

    @property
    def contours(self) -> list[NDArray[np.float64]]:
        """The current contour of each piece (copies)."""
        return [t.nodes for t in self.trackers]

    def step(self, frame: NDArray[np.uint8]) -> PiecesResult:
        """Track every piece into the next frame (see :meth:`Tracker.step`)."""
        return self.step_prepared(*as_frame(frame))

    def step_prepared(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        crowd: Crowd | None = None,
    ) -> PiecesResult:
        """:meth:`step` on a frame checked and converted once (:meth:`Tracker.step_prepared`,
        ``crowd`` as there).  A noisy frame is smoothed once for all the pieces, and a frame
        tracked downscaled brought down once."""
        crowd = crowd or Crowd()
        if crowd.smoothing is None:
            crowd = replace(crowd, smoothing=Smoothing(image, grey))
        if crowd.working is None:
            crowd = replace(crowd, working=WorkingFrames(image, grey))
        pieces = [t.step_prepared(image, grey, crowd) for t in self.trackers]
        weights = np.array([abs(polygon_area(p.nodes)) for p in pieces]) + 1.0
        confidence = float(np.dot(weights, [p.confidence for p in pieces]) / weights.sum())
        return PiecesResult([p.nodes for p in pieces], confidence, status_of(confidence), pieces)

    def to_state(self, **kwargs: Any) -> dict[str, Any]:
        """``{"kind": "pieces", "pieces": [Tracker state, ...]}`` (``kwargs`` as
        :meth:`Tracker.to_state`'s)."""
        return {"kind": KIND, "pieces": [t.to_state(**kwargs) for t in self.trackers]}

    @classmethod
    def from_state(cls, state: Mapping[str, Any]) -> PiecesTracker:
        """Rebuild from :meth:`to_state` output; ValueError if malformed."""
        if not isinstance(state, Mapping) or state.get("kind") != KIND:
            raise ValueError("a pieces tracker state must be a dict of kind 'pieces'")
        pieces = state.get("pieces")
        if not isinstance(pieces, list) or not pieces:
            raise ValueError("a pieces tracker state needs a non-empty list of pieces")
        restored = cls.__new__(cls)
        restored.trackers = [Tracker.from_state(p) for p in pieces]
        return restored
