"""``ObjectsTracker``: several objects through the same frames, each with its own id.

Each object is a :class:`Tracker` (one closed contour) or a
:class:`PiecesTracker` (several pieces); objects can be added, replaced (a
user's correction: the object learns anew from it on the next frame) and
removed between frames.  The frame is checked and converted once; the
objects' own work then runs one after the other, on a pool of threads
(``workers``; OpenCV and the compiled kernels release the GIL, but the trackers
hold it for much of their time, so a second thread gains little), or on
``workers`` processes (``processes=True``: each holds its share of the
trackers, and a frame reaches them once, through shared memory;
:mod:`engine.tracking._processes`).  With two
objects or more, the background's motion and the dense flow are measured once
over the whole frame (:mod:`engine.tracking.shared`).

Where two objects overlap, the one in front is read from the frame: over the
pixels both silhouettes claim, the object whose appearance model finds them
more object-like shows there (:func:`engine.tracking.covering.fronts`).  It is
tracked first, and the pixels it covers are neutral to the one behind, which
keeps its whole outline and goes on under it (:mod:`engine.tracking.covering`);
:func:`label_mask` gives each overlapping pixel to the object in front.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Hashable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import contour_to_mask
from engine.tracking._processes import (
    Remote,
    Workers,
    contours_of,
    probability_of,
    restore,
    started,
)
from engine.tracking.confidence import Status
from engine.tracking.covering import Order, Silhouette, fronts
from engine.tracking.lighting import Lighting
from engine.tracking.noise import Smoothing
from engine.tracking.options import TrackerOptions
from engine.tracking.pieces import PiecesTracker
from engine.tracking.shared import Crowd, SharedLight, SharedMotion
from engine.tracking.tracker import Tracker
from engine.tracking.working import WORKING_SIDE, WorkingFrames, WorkingScale, working_scale

__all__ = ["ObjectResult", "ObjectsTracker", "label_mask"]

KIND = "objects"
MAX_OBJECTS = 32
"""Objects one tracker follows at most by default (a frame's cost grows with each)."""
_OPTION_NAMES = frozenset(f.name for f in dataclasses.fields(TrackerOptions))
"""The options a state keeps: :class:`TrackerOptions` fields (not stages given as objects)."""


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
    behind : tuple
        The ids of the objects found in front of it where they overlapped
        (:func:`engine.tracking.covering.fronts`); empty when nothing covers it.
    """

    id: Hashable
    contours: list[NDArray[np.float64]]
    confidence: float
    status: Status
    behind: tuple[Hashable, ...] = ()


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
        Threads the objects are tracked on (1: one after the other), or
        processes with ``processes``.
    processes : bool
        Track the objects on ``workers`` worker processes (started with the
        first object, ended by :meth:`close`), each holding its share of the
        trackers: results are the same, bit for bit, as in this process.
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
        processes: bool = False,
        **options: Any,
    ) -> None:
        if max_objects < 1 or workers < 1:
            raise ValueError("max_objects and workers must be at least 1")
        self.max_objects, self.workers, self.options = max_objects, workers, dict(options)
        self.trackers: dict[Hashable, Tracker | PiecesTracker | Remote] = {}
        self._workers = Workers(workers) if processes else None
        # the last grey frame, for the whole-frame measurements (engine.tracking.shared)
        self._previous: NDArray[np.uint8] | None = None
        # and the last colour frame on the lighting's grid (engine.tracking.lighting)
        self._light: NDArray[np.uint8] | None = None
        # made on first use with workers > 1 and kept (a pool a frame cost more than the
        # second thread gave); its idle threads end with the tracker, or with close()
        self._pool: ThreadPoolExecutor | None = None
        self._order: Order = {}  # which of two overlapping objects is in front
        for key, outline in (objects or {}).items():
            self.add(key, outline)

    def _make(self, outline: ArrayLike | Sequence[ArrayLike]) -> Tracker | PiecesTracker | Remote:
        return self._held(self._build(outline))

    def _build(self, outline: ArrayLike | Sequence[ArrayLike]) -> Tracker | PiecesTracker:
        tracker: Tracker | PiecesTracker
        if isinstance(outline, list | tuple) and _is_list_of_contours(outline):
            pieces = list(outline)
            if len(pieces) > 1:
                tracker = PiecesTracker(pieces, **self.options)
            else:
                tracker = Tracker(pieces[0], **self.options)
        else:
            tracker = Tracker(np.asarray(outline, dtype=np.float64), **self.options)
        return tracker

    def _held(self, tracker: Tracker | PiecesTracker) -> Tracker | PiecesTracker | Remote:
        """``tracker`` itself, or handed to a worker process."""
        return tracker if self._workers is None else self._workers.place(tracker)

    def _let_go(self, key: Hashable) -> None:
        """A worker process forgets the tracker of ``key`` (a correction or removal)."""
        old = self.trackers[key]
        if isinstance(old, Remote) and self._workers is not None:
            self._workers.drop(old)

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
        made = self._make(outline)
        self._let_go(key)
        self.trackers[key] = made
        self._forget_order(key)

    def restart(
        self, key: Hashable, outline: ArrayLike | Sequence[ArrayLike], frame: NDArray[np.uint8]
    ) -> None:
        """A correction of the frame just tracked: object ``key`` starts anew from ``outline``
        on ``frame`` (that frame, given again) and goes on from there with the next, as if
        ``outline`` had been given before it (KeyError if unknown, ValueError if malformed).
        """
        if key not in self.trackers:
            raise KeyError(key)
        made = self._build(outline)
        made.step(frame)  # a first frame only starts a tracker: the others do not matter
        self._let_go(key)
        self.trackers[key] = self._held(made)
        self._forget_order(key)

    def remove(self, key: Hashable) -> None:
        """Stop following an object (KeyError if unknown)."""
        if key not in self.trackers:
            raise KeyError(key)
        self._let_go(key)
        del self.trackers[key]
        self._forget_order(key)

    def close(self) -> None:
        """End the pool of threads now (it is made again should a frame need it), and the
        worker processes: their objects come back to this process (their states, exactly)
        and are tracked here from then on."""
        if self._pool is not None:
            self._pool.shutdown()
            self._pool = None
        if self._workers is not None:
            for key, tracker in self.trackers.items():
                if isinstance(tracker, Remote):
                    self.trackers[key] = restore(tracker.to_state())
            self._workers.close()
            self._workers = None

    def _forget_order(self, key: Hashable) -> None:
        """Drop the overlap orders ``key`` had: it starts anew, or is gone."""
        self._order = {pair: front for pair, front in self._order.items() if key not in pair}

    def contours(self, key: Hashable) -> list[NDArray[np.float64]]:
        """Object ``key``'s current contour, or one per piece (KeyError if unknown)."""
        tracker = self.trackers[key]
        if isinstance(tracker, Remote):
            return list(tracker.contours)
        return tracker.contours if isinstance(tracker, PiecesTracker) else [tracker.nodes]

    def step(self, frame: NDArray[np.uint8]) -> list[ObjectResult]:
        """Track every object into the next frame; results in the order objects were added.

        Where objects overlapped in the last frame, the one in front
        (:func:`engine.tracking.covering.fronts`) is tracked first, and the pixels it
        covers, in the last frame and this one, are neutral to the one behind.
        """
        from engine.tracking._frames import as_frame

        # checked once, a clear error before any object moves; converted to grey once
        image, grey = as_frame(frame)
        shape = grey.shape
        # a noisy frame smoothed once for every object, and what the session itself reads
        # of the frame's colours (who is in front, the change of light) read from it, as
        # each object's tracker reads them (the frame itself on clean video); on frames
        # tracked downscaled the working grid is made, and smoothed if noisy there, once for
        # the trackers (``working``), and who is in front is read from the frame as it is
        smoothing, working = Smoothing(image, grey), WorkingFrames(image, grey)
        downscaled = working_scale(shape, self.options.get("working_side", WORKING_SIDE))
        colours = image if image.ndim == 2 or downscaled else smoothing.of(image, grey)
        # the whole frame's motion and light are measured where the trackers read them: on
        # the frame, or on the working grid they are all tracked on (none to track: the frame)
        if downscaled is None or not self.trackers:
            downscaled, measured_on = None, (colours, grey)
        else:
            small, small_grey, grid_smoothing = working.at(downscaled, image, grey)
            grid_colours = small if small.ndim == 2 else grid_smoothing.of(small, small_grey)
            measured_on = (grid_colours, small_grey)
        silhouettes = {
            key: found
            for key, tracker in self.trackers.items()
            if started(tracker) and (found := Silhouette.of(self.contours(key), shape))
        }

        def probability(key: Hashable, box: tuple[int, int, int, int]) -> NDArray[np.float32]:
            x0, y0, x1, y1 = box
            return probability_of(self.trackers[key], colours[y0:y1, x0:x1])

        in_front, self._order = fronts(silhouettes, probability, self._order)
        shared = self._shared(*measured_on, silhouettes, downscaled)
        if self._workers is not None and self.trackers:
            self._workers.frame(image, grey, shared, downscaled)
        self._previous = measured_on[1]
        results: dict[Hashable, Any] = {}
        waiting = list(self.trackers)
        while waiting:
            # the objects whose fronts are done (all left, should the fronts form a loop)
            wave = [k for k in waiting if all(f in results for f in in_front.get(k, []))]
            wave = wave or waiting
            covers = {
                key: self._covered(key, in_front, silhouettes, results, shape) for key in wave
            }
            done = self._step_wave(image, grey, wave, covers, shared, smoothing, working)
            results.update(zip(wave, done, strict=True))
            waiting = [k for k in waiting if k not in results]
        out = []
        for key in self.trackers:
            r = results[key]
            behind = tuple(in_front.get(key, ()))
            out.append(ObjectResult(key, contours_of(r), float(r.confidence), r.status, behind))
        return out

    def _shared(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        silhouettes: Mapping[Hashable, Silhouette],
        scale: WorkingScale | None = None,
    ) -> SharedMotion | None:
        """The whole frame's background motion, flow and change of light, when two or more
        objects go on from the last frame (one object measures around itself, as a tracker
        alone).  On frames tracked downscaled, ``scale`` given, ``image`` and ``grey`` are
        the working grid's (:mod:`engine.tracking.working`), and so are the measures."""
        previous, light = self._previous, None
        if len(silhouettes) >= 2 and self.options.get("lighting", True) is not False:
            sample, step = Lighting.whole(self._light, image)
            light = SharedLight(sample, step) if self._light is not None else None
            self._light = sample
        else:
            self._light = None
        if len(silhouettes) < 2 or previous is None or previous.shape != grey.shape:
            return None
        excluded = np.zeros(grey.shape if scale is None else scale.frame_shape, np.bool_)
        for silhouette in silhouettes.values():
            silhouette.paint(excluded)
        if scale is not None:
            excluded = scale.mask(excluded)
        return SharedMotion.measure(previous, grey, excluded, light)

    def _step_wave(
        self,
        image: NDArray[np.uint8],
        grey: NDArray[np.uint8],
        wave: list[Hashable],
        covers: Mapping[Hashable, NDArray[np.bool_] | None],
        shared: SharedMotion | None,
        smoothing: Smoothing,
        working: WorkingFrames,
    ) -> list[Any]:
        """Track the objects of ``wave`` (on the worker processes, or the pool of threads,
        when there is one; each process smooths a noisy frame, and brings a large one down
        to the working grid, once for its objects)."""
        if self._workers is not None:
            return self._workers.step([(self.trackers[k], covers[k]) for k in wave])

        def one(key: Hashable) -> Any:
            tracker = self.trackers[key]
            assert not isinstance(tracker, Remote)
            crowd = Crowd(covers[key], shared, smoothing, working)
            return tracker.step_prepared(image, grey, crowd)

        if self.workers > 1 and len(wave) > 1:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="efdm-objects")
            return list(self._pool.map(one, wave))
        return [one(key) for key in wave]

    @staticmethod
    def _covered(
        key: Hashable,
        in_front: Mapping[Hashable, list[Hashable]],
        silhouettes: Mapping[Hashable, Silhouette],
        results: Mapping[Hashable, Any],
        shape: tuple[int, int],
    ) -> NDArray[np.bool_] | None:
        """What the objects in front of ``key`` hide: their last and (when done) new silhouettes."""
        front = in_front.get(key, [])
        if not front:
            return None
        covered = np.zeros(shape, np.bool_)
        for other in front:
            silhouettes[other].paint(covered)
            if other in results:
                now = Silhouette.of(contours_of(results[other]), shape)
                if now is not None:
                    now.paint(covered)
        return covered

    def to_state(self, **kwargs: Any) -> dict[str, Any]:
        """``{"kind": "objects", "max_objects", "options", "objects": [[id, state], ...],
        "in_front": [[front id, back id], ...]}``, JSON-able for JSON-able ids (``kwargs`` as
        :meth:`Tracker.to_state`'s).  ``options`` are the :class:`TrackerOptions` fields
        given (stages passed as objects are not kept): objects added after a resume are
        tracked with them, and they decide what is measured once for all objects."""
        pairs = [[front, next(iter(pair - {front}))] for pair, front in self._order.items()]
        return {
            "kind": KIND,
            "max_objects": self.max_objects,
            "options": {k: v for k, v in self.options.items() if k in _OPTION_NAMES},
            "objects": [[key, t.to_state(**kwargs)] for key, t in self.trackers.items()],
            "in_front": pairs,
        }

    @classmethod
    def from_state(
        cls, state: Mapping[str, Any], *, workers: int = 1, processes: bool = False
    ) -> ObjectsTracker:
        """Rebuild from :meth:`to_state` output; ValueError if malformed."""
        if not isinstance(state, Mapping) or state.get("kind") != KIND:
            raise ValueError("an objects tracker state must be a dict of kind 'objects'")
        entries = state.get("objects")
        if not isinstance(entries, list):
            raise ValueError("an objects tracker state needs a list of objects")
        options = state.get("options", {})  # states written before it was kept: none
        if not isinstance(options, Mapping) or not all(isinstance(k, str) for k in options):
            raise ValueError("an objects tracker state's options must be a dict of option names")
        try:  # checked here, before any object is rebuilt
            TrackerOptions.from_mapping(options)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"an objects tracker state's options: {exc}") from None
        frames: list[NDArray[np.uint8] | None] = []
        restored = cls(
            max_objects=int(state.get("max_objects", MAX_OBJECTS)),
            workers=workers,
            processes=processes,
            **options,
        )
        for entry in entries:
            if not isinstance(entry, list | tuple) or len(entry) != 2:
                raise ValueError("each object of the state must be [id, state]")
            key, inner = entry[0], entry[1]
            key = _object_id(key)
            if key in restored.trackers or len(restored.trackers) >= restored.max_objects:
                raise ValueError(f"object {key!r}: repeated, or one too many")
            tracker = restore(inner)
            frames.append(_previous_frame(tracker))
            restored.trackers[key] = restored._held(tracker)
        # the frame they go on from (each tracker checks it is its own)
        restored._previous = next((f for f in frames if f is not None), None)
        restored._order = _order_of(state.get("in_front", []), restored.trackers)
        return restored


def _object_id(raw: object) -> Hashable:
    """An object id read from a state: a list back to the tuple JSON made of it; ValueError
    for one that cannot be an id (a dict, a list holding one)."""
    key = tuple(raw) if isinstance(raw, list) else raw
    try:
        hash(key)
    except TypeError:
        raise ValueError(f"an object id must be a string or a number; got {raw!r}") from None
    return key


def _order_of(pairs: object, known: Mapping[Hashable, object]) -> Order:
    """The ``"in_front"`` pairs of a state, checked against the objects' ids."""
    if not isinstance(pairs, list):
        raise ValueError("an objects tracker state's in_front must be a list of id pairs")
    order: Order = {}
    for pair in pairs:
        if not isinstance(pair, list | tuple) or len(pair) != 2:
            raise ValueError("each in_front pair of an objects tracker state must be [front, back]")
        front, back = (_object_id(k) for k in pair)
        if front not in known or back not in known or front == back:
            raise ValueError(f"in_front pair {pair!r}: not two of the state's objects")
        order[frozenset((front, back))] = front
    return order


def _previous_frame(tracker: Tracker | PiecesTracker) -> NDArray[np.uint8] | None:
    """The grey frame the tracker's contour is on (its first piece's)."""
    first = tracker.trackers[0] if isinstance(tracker, PiecesTracker) else tracker
    return first.previous_frame


def _is_list_of_contours(value: Sequence[object]) -> bool:
    """Whether ``value`` is a list of (N, 2) contours rather than one contour's points."""
    return len(value) > 0 and all(np.asarray(v).ndim == 2 for v in value)


def label_mask(results: Sequence[ObjectResult], shape: tuple[int, int]) -> NDArray[np.int32]:
    """Each pixel's object: the index into ``results`` plus 1 (0: none).

    Where contours overlap, the object in front wins the pixel: the one with the
    fewest objects in front of it (:attr:`ObjectResult.behind`), and of those the
    more confident.
    """
    labels = np.zeros(shape, np.int32)
    best = np.full(shape, -np.inf)
    for index, result in enumerate(results):
        inside = np.zeros(shape, np.uint8)
        for contour in result.contours:
            inside |= contour_to_mask(contour, shape)
        # fewer objects in front first; confidence (in [0, 1]) breaks ties
        rank = result.confidence - 2.0 * len(result.behind)
        wins = (inside > 0) & (rank > best)
        labels[wins] = index + 1
        best[wins] = rank
    return labels
