"""``ObjectsTracker``: several objects through the same frames, each with its own id.

Each object is a :class:`Tracker` (one closed contour) or a
:class:`PiecesTracker` (several pieces); objects can be added, replaced (a
user's correction: the object learns anew from it on the next frame) and
removed between frames.  The frame is checked and converted once; the
objects' own work then runs one after the other, or on a pool of threads
(``workers``: OpenCV and the compiled kernels release the GIL).

Where two objects' contours overlap, each keeps its own contour (they are
outlines, and an object behind another goes on under it, as with any
occluder); :func:`label_mask` gives each overlapping pixel to the object
whose track is the more confident, taken to be the one in front.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import contour_to_mask
from engine.tracking.confidence import Status
from engine.tracking.pieces import PiecesTracker
from engine.tracking.tracker import Tracker

__all__ = ["ObjectResult", "ObjectsTracker", "label_mask"]

KIND = "objects"
MAX_OBJECTS = 32
"""Objects one tracker follows at most by default (a frame's cost grows with each)."""


@dataclass(frozen=True, slots=True)
class ObjectResult:
    """One object's result for a frame.

    Attributes
    ----------
    id : hashable
        The object's id.
    contours : list of numpy.ndarray
        Its contour, or one per piece, (N_i, 2) ``[x, y]`` pixels.
    confidence : float
        In [0, 1], the predicted overlap with the object.
    status : {"tracking", "uncertain", "lost"}
        From the confidence.
    """

    id: Hashable
    contours: list[NDArray[np.float64]]
    confidence: float
    status: Status


class ObjectsTracker:
    """Follows up to ``max_objects`` objects through the same frames.

    Parameters
    ----------
    objects : mapping, optional
        Object id -> its contour ((N, 2) array_like) or a list of contours
        (one per piece).
    max_objects : int
        Most objects at once (:data:`MAX_OBJECTS`).
    workers : int
        Threads the objects are tracked on (1: one after the other).
    **options
        :class:`TrackerOptions` fields, for every object.

    Raises
    ------
    ValueError
        On too many objects, a malformed contour or an invalid option.
    """

    def __init__(
        self,
        objects: Mapping[Any, ArrayLike | Sequence[ArrayLike]] | None = None,
        *,
        max_objects: int = MAX_OBJECTS,
        workers: int = 1,
        **options: Any,
    ) -> None:
        if max_objects < 1 or workers < 1:
            raise ValueError("max_objects and workers must be at least 1")
        self.max_objects, self.workers, self.options = max_objects, workers, dict(options)
        self.trackers: dict[Hashable, Tracker | PiecesTracker] = {}
        for key, outline in (objects or {}).items():
            self.add(key, outline)

    def _make(self, outline: ArrayLike | Sequence[ArrayLike]) -> Tracker | PiecesTracker:
        if isinstance(outline, list | tuple) and _is_list_of_contours(outline):
            pieces = list(outline)
            if len(pieces) > 1:
                return PiecesTracker(pieces, **self.options)
            return Tracker(pieces[0], **self.options)
        return Tracker(np.asarray(outline, dtype=np.float64), **self.options)

    def add(self, key: Hashable, outline: ArrayLike | Sequence[ArrayLike]) -> None:
        """Follow a new object from the next frame on (ValueError if ``key`` is taken)."""
        if key in self.trackers:
            raise ValueError(f"object {key!r} exists already")
        if len(self.trackers) >= self.max_objects:
            raise ValueError(f"at most {self.max_objects} objects")
        self.trackers[key] = self._make(outline)

    def replace(self, key: Hashable, outline: ArrayLike | Sequence[ArrayLike]) -> None:
        """A correction: the object starts anew from ``outline`` on the next frame."""
        if key not in self.trackers:
            raise KeyError(key)
        self.trackers[key] = self._make(outline)

    def remove(self, key: Hashable) -> None:
        """Stop following an object (KeyError if unknown)."""
        del self.trackers[key]

    def contours(self, key: Hashable) -> list[NDArray[np.float64]]:
        """Object ``key``'s current contour, or one per piece (KeyError if unknown)."""
        tracker = self.trackers[key]
        return tracker.contours if isinstance(tracker, PiecesTracker) else [tracker.nodes]

    def step(self, frame: NDArray[np.uint8]) -> list[ObjectResult]:
        """Track every object into the next frame, in the order they were added."""
        from engine.tracking._frames import as_frame

        # checked once, a clear error before any object moves; converted to grey once
        image, grey = as_frame(frame)
        items = list(self.trackers.items())
        if self.workers > 1 and len(items) > 1:
            with ThreadPoolExecutor(min(self.workers, len(items))) as pool:
                results = list(pool.map(lambda kv: kv[1].step_prepared(image, grey), items))
        else:
            results = [t.step_prepared(image, grey) for _, t in items]
        out = []
        for (key, _), r in zip(items, results, strict=True):
            contours = list(r.contours) if hasattr(r, "contours") else [r.nodes]
            out.append(ObjectResult(key, contours, float(r.confidence), r.status))
        return out

    def to_state(self, **kwargs: Any) -> dict[str, Any]:
        """``{"kind": "objects", "max_objects", "objects": [[id, state], ...]}``, JSON-able
        for JSON-able ids (``kwargs`` as :meth:`Tracker.to_state`'s)."""
        return {
            "kind": KIND,
            "max_objects": self.max_objects,
            "objects": [[key, t.to_state(**kwargs)] for key, t in self.trackers.items()],
        }

    @classmethod
    def from_state(cls, state: Mapping[str, Any], *, workers: int = 1) -> ObjectsTracker:
        """Rebuild from :meth:`to_state` output; ValueError if malformed."""
        if not isinstance(state, Mapping) or state.get("kind") != KIND:
            raise ValueError("an objects tracker state must be a dict of kind 'objects'")
        entries = state.get("objects")
        if not isinstance(entries, list):
            raise ValueError("an objects tracker state needs a list of objects")
        restored = cls(max_objects=int(state.get("max_objects", MAX_OBJECTS)), workers=workers)
        for entry in entries:
            if not isinstance(entry, list | tuple) or len(entry) != 2:
                raise ValueError("each object of the state must be [id, state]")
            key, inner = entry
            key = tuple(key) if isinstance(key, list) else key  # JSON turns tuples into lists
            if key in restored.trackers or len(restored.trackers) >= restored.max_objects:
                raise ValueError(f"object {key!r}: repeated, or one too many")
            is_pieces = isinstance(inner, Mapping) and inner.get("kind") == "pieces"
            tracker = PiecesTracker.from_state(inner) if is_pieces else Tracker.from_state(inner)
            restored.trackers[key] = tracker
        return restored


def _is_list_of_contours(value: Sequence[object]) -> bool:
    """Whether ``value`` is a list of (N, 2) contours rather than one contour's points."""
    return len(value) > 0 and all(np.asarray(v).ndim == 2 for v in value)


def label_mask(results: Sequence[ObjectResult], shape: tuple[int, int]) -> NDArray[np.int32]:
    """Each pixel's object: the index into ``results`` plus 1 (0: none).

    Where contours overlap, the more confident object is taken to be in front
    and wins the pixel.
    """
    labels = np.zeros(shape, np.int32)
    best = np.full(shape, -1.0)
    for index, result in enumerate(results):
        inside = np.zeros(shape, np.uint8)
        for contour in result.contours:
            inside |= contour_to_mask(contour, shape)
        wins = (inside > 0) & (result.confidence > best)
        labels[wins] = index + 1
        best[wins] = result.confidence
    return labels
