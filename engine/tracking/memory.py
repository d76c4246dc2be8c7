"""``Memory``: what the tracker remembers of the object beyond the last frame.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.geometry import as_nodes
from engine.tracking._state_codec import count, factors

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
    """

    misses: int
    probation: int
    shape: NDArray[np.float64]
    hold: NDArray[np.float64]
    outline: NDArray[np.float64] | None = None

    @classmethod
    def fresh(cls, nodes: NDArray[np.float64]) -> Memory:
        """Nothing missed, the given contour as the shape, no node held, no outline."""
        return cls(0, 0, nodes, np.zeros(len(nodes)))

    def to_state(self) -> dict[str, Any]:
        """``{"misses", "probation", "shape", "hold", "outline"}``, JSON-able."""
        return {
            "misses": self.misses,
            "probation": self.probation,
            "shape": self.shape.tolist(),
            "hold": self.hold.tolist(),
            "outline": None if self.outline is None else self.outline.tolist(),
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any], nodes: int) -> Memory:
        """Inverse of :meth:`to_state` for a contour of ``nodes`` nodes; ValueError if malformed.

        A state without ``"outline"`` (written before the shape memory) has none.
        """
        outline = state.get("outline")
        return cls(
            count(state["misses"]),
            count(state["probation"]),
            as_nodes(state["shape"]),
            factors(state["hold"], nodes),
            None if outline is None else as_nodes(outline),
        )
