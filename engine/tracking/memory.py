"""``Memory``: what the tracker remembers of the object beyond the last frame.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes
from engine.tracking._state_codec import count, factors
from engine.tracking.confidence import USUAL_FRAMES
from engine.tracking.recent_shapes import RecentShapes

__all__ = ["Memory"]


@dataclass(slots=True)
class Memory:
    """The search's and the holding's memory (:mod:`~engine.tracking.reacquisition`,
    :mod:`~engine.tracking.holding`).

    Attributes
    ----------
    misses : int
        Frames in a row that did not end confident (the search window grows with them).
    probation : int
        Frames left to report a re-acquired contour ``uncertain``.
    shape : numpy.ndarray
        (M, 2) ``[x, y]`` contour of the last confident frame: the shape searched for.
    hold : numpy.ndarray
        (N,) per node of the current contour, in [0, 1]: how far it holds the shape
        where both its sides look alike.
    outline : numpy.ndarray or None
        (M, 2) ``[x, y]`` the first frame's contour where it is now
        (:mod:`~engine.tracking.shape_memory`); None: no shape memory.
    usual : numpy.ndarray
        (2,) mean p(object) inside the contour and in the ring outside it over the
        track's first :data:`~engine.tracking.confidence.USUAL_FRAMES` tracked
        frames: how this object looks against its surroundings
        (:class:`~engine.tracking.confidence.Evidence`).
    usual_count : int
        Frames counted in ``usual`` so far.
    reacquired : bool
        Whether the current run of misses already ended in a re-acquisition (the
        remembered shape was put back once; it is not searched for again on the way back).
    jumped : bool
        Whether the last re-acquisition moved the contour away from the local one
        (:func:`~engine.tracking.reacquisition.jumped`): only then are the frames of its
        probation reported ``uncertain``.
    marks : numpy.ndarray or None
        (M,) per point of ``outline``, in [0, 1]: how far the node there was held on
        the first frame (``hold`` then).  They ride on the outline, which turns with
        the object (:mod:`~engine.tracking.turn`); None: only ``hold`` is known, and
        it rides on the contour's nodes.
    recent : RecentShapes
        The shapes of the last frames on the object, which the confidence
        compares a contour's shape with besides the outline
        (:mod:`~engine.tracking.recent_shapes`).
    """

    misses: int
    probation: int
    shape: NDArray[np.float64]
    hold: NDArray[np.float64]
    outline: NDArray[np.float64] | None = None
    usual: NDArray[np.float64] = field(default_factory=lambda: np.zeros(2))
    usual_count: int = 0
    reacquired: bool = False
    jumped: bool = True
    marks: NDArray[np.float64] | None = None
    recent: RecentShapes = field(default_factory=RecentShapes)

    @classmethod
    def fresh(cls, nodes: NDArray[np.float64]) -> Memory:
        """Nothing missed, the given contour as the shape, no node held, no outline, no
        usual look yet."""
        return cls(0, 0, nodes, np.zeros(len(nodes)))

    def usual_with(self, inside: float, outside: float) -> tuple[float, float]:
        """``usual`` with a frame of mean p(object) ``inside`` and ``outside`` counted in,
        while fewer than :data:`~engine.tracking.confidence.USUAL_FRAMES` are."""
        n = self.usual_count
        if n >= USUAL_FRAMES:
            return float(self.usual[0]), float(self.usual[1])
        return (self.usual[0] * n + inside) / (n + 1), (self.usual[1] * n + outside) / (n + 1)

    def learn_usual(self, inside: float, outside: float) -> None:
        """Count a tracked frame in ``usual`` (:meth:`usual_with`)."""
        if self.usual_count < USUAL_FRAMES:
            self.usual = np.array(self.usual_with(inside, outside), np.float64)
            self.usual_count += 1

    def to_state(self) -> dict[str, Any]:
        """``{"misses", "probation", "shape", "hold", "outline", "usual", "reacquired",
        "jumped", "recent"}`` and ``"marks"`` when known, JSON-able (``"usual"``: ``[inside,
        outside, frames counted]``)."""
        state: dict[str, Any] = {
            "misses": self.misses,
            "probation": self.probation,
            "shape": self.shape.tolist(),
            "hold": self.hold.tolist(),
            "outline": None if self.outline is None else self.outline.tolist(),
            "usual": [float(self.usual[0]), float(self.usual[1]), self.usual_count],
            "reacquired": self.reacquired,
            "jumped": self.jumped,
            "recent": self.recent.to_state(),
        }
        if self.marks is not None:
            state["marks"] = self.marks.tolist()
        return state

    @classmethod
    def from_state(cls, state: Mapping[str, Any], nodes: int) -> Memory:
        """Inverse of :meth:`to_state` for a contour of ``nodes`` nodes; ValueError if malformed.

        A state without ``"outline"`` (written before the shape memory) has none; one
        without ``"usual"`` (written before it) counts the usual look from its next frames;
        one without ``"reacquired"`` (written before it) has not re-acquired; one without
        ``"jumped"`` (written when every re-acquisition was on probation) reports its
        probation's frames ``uncertain``; one without ``"marks"`` (written before the
        outline turned) keeps its marks on the contour's nodes; one without ``"recent"``
        (written before the recent shapes) has none yet.  Marks need an outline, one per
        point.
        """
        if not isinstance(state, Mapping):
            raise ValueError(f"the search state must be a dict; got {type(state).__name__}")
        outline = None if state.get("outline") is None else as_nodes(state["outline"])
        marks = state.get("marks")
        if marks is not None:
            if outline is None:
                raise ValueError("marks need an outline")
            marks = factors(marks, len(outline))
        usual = state.get("usual", [0.0, 0.0, 0])
        if not isinstance(usual, list | tuple) or len(usual) != 3:
            raise ValueError(f"usual must be [inside, outside, frames]; got {usual!r}")
        means = factors(usual[:2], 2)
        frames = count(usual[2])
        if frames > USUAL_FRAMES:
            raise ValueError(f"usual counts at most {USUAL_FRAMES} frames; got {frames}")
        reacquired = state.get("reacquired", False)
        if not isinstance(reacquired, bool):
            raise ValueError(f"reacquired must be true or false; got {reacquired!r}")
        jumped = state.get("jumped", True)
        if not isinstance(jumped, bool):
            raise ValueError(f"jumped must be true or false; got {jumped!r}")
        return cls(
            count(state["misses"]),
            count(state["probation"]),
            as_nodes(state["shape"]),
            factors(state["hold"], nodes),
            outline,
            means,
            frames,
            reacquired,
            jumped,
            marks,
            RecentShapes.from_state(state.get("recent", [])),
        )
