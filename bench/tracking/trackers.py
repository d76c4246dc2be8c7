"""The contour trackers compared by the tracking benchmark, behind one interface.

Every tracker is constructed from the initial contours (one ``(N, 2)`` ``[x, y]``
array per separate piece of the object, the largest first; usually one) and then fed
the frames in order, starting with frame 0; each :meth:`ContourTracker.step` returns
the contours on that frame.

- ``"efdm"``: ``engine.Tracker``, or ``engine.tracking.PiecesTracker`` for an object in
  several pieces, as ``efdm track --init-mask`` runs them (imported lazily: the others
  run without it).
- ``"static"``: the contours never move.
- ``"skimage"``: ``skimage.segmentation.active_contour`` frame by frame, one snake a
  piece, initialised from the previous frame's result, on the grey frame smoothed by
  ``skimage.filters.gaussian(sigma=2)``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.common.data import Frame

Nodes = NDArray[np.float64]

TRACKERS = ("efdm", "static", "skimage")
SKIMAGE_PARAMS: dict[str, Any] = {
    "alpha": 0.01,
    "beta": 0.1,
    "gamma": 0.01,
    "w_edge": 1.0,
    "w_line": 0.0,
    "max_num_iter": 50,
    "boundary_condition": "periodic",
}
"""``active_contour`` keyword arguments: the DAVIS README's reference settings."""
SKIMAGE_SIGMA = 2.0
EFDM_EXTRAS = ("iterations", "converged", "confidence")
"""Per-frame diagnostics read from ``engine.Tracker``'s step results when present."""
STATUSES = ("tracking", "uncertain", "lost")
"""What ``engine.Tracker`` says of each frame (``TrackResult.status``)."""


@dataclass(frozen=True, slots=True)
class Step:
    """A tracker's answer for one frame.

    Attributes
    ----------
    nodes : numpy.ndarray
        ``(N, 2)`` ``[x, y]`` contour on this frame (of the first piece).
    extras : dict of str to float
        Diagnostics (efdm: iterations, converged, confidence).
    status : str or None
        The tracker's own verdict on the frame (efdm: one of :data:`STATUSES`).
    others : tuple of numpy.ndarray
        The other pieces' contours, for an object in several pieces.
    """

    nodes: Nodes
    extras: dict[str, float] = field(default_factory=dict)
    status: str | None = None
    others: tuple[Nodes, ...] = ()

    @property
    def contours(self) -> list[Nodes]:
        """Every piece's contour, the first piece's first."""
        return [self.nodes, *self.others]


class ContourTracker(Protocol):
    """What the benchmark needs of a tracker."""

    def step(self, frame: Frame) -> Step:
        """Track into the next frame (the first call sees frame 0)."""
        ...


Factory = Callable[[Sequence[Nodes]], ContourTracker]
"""Builds a tracker from the initial contours: one per piece, the largest first."""


def _pieces(contours: Sequence[Nodes]) -> list[Nodes]:
    """Copies of the initial contours; ValueError when there are none."""
    if len(contours) == 0:
        raise ValueError("a tracker needs at least one initial contour")
    return [np.array(c, dtype=np.float64) for c in contours]


class StaticTracker:
    """The contours never move."""

    def __init__(self, contours: Sequence[Nodes]) -> None:
        self._contours = _pieces(contours)

    def step(self, frame: Frame) -> Step:
        """Return the initial contours whatever the frame."""
        return Step(self._contours[0], others=tuple(self._contours[1:]))


class SkimageTracker:
    """``skimage.segmentation.active_contour`` run on every frame from the last result,
    one snake a piece."""

    def __init__(self, contours: Sequence[Nodes]) -> None:
        from skimage.filters import gaussian
        from skimage.segmentation import active_contour

        self._gaussian: Callable[..., Any] = gaussian
        self._active_contour: Callable[..., Any] = active_contour
        self._contours = _pieces(contours)
        self._started = False

    def step(self, frame: Frame) -> Step:
        """Frame 0: the initial contours; later frames: the snakes from the last result."""
        if self._started:
            grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
            smooth = self._gaussian(grey, sigma=SKIMAGE_SIGMA)
            self._contours = [self._snake(smooth, nodes) for nodes in self._contours]
        self._started = True
        copies = [c.copy() for c in self._contours]
        return Step(copies[0], others=tuple(copies[1:]))

    def _snake(self, smooth: NDArray[np.float64], nodes: Nodes) -> Nodes:
        """One snake's result from ``nodes`` on the smoothed frame, ``[x, y]``."""
        snake = self._active_contour(smooth, nodes[:, ::-1], **SKIMAGE_PARAMS)
        return np.ascontiguousarray(np.asarray(snake, dtype=np.float64)[:, ::-1])


class EfdmTracker:
    """Adapter for ``engine.Tracker`` and ``PiecesTracker`` (``step(frame)`` returns
    ``.nodes`` or ``.contours``, diagnostics, status)."""

    def __init__(self, engine_tracker: Any) -> None:
        self._tracker = engine_tracker

    def step(self, frame: Frame) -> Step:
        """One ``step`` of the engine's tracker; its contours, diagnostics and status."""
        result = self._tracker.step(frame)
        contours = [
            np.asarray(c, dtype=np.float64) for c in getattr(result, "contours", [result.nodes])
        ]
        for nodes in contours:
            if nodes.ndim != 2 or nodes.shape[1] != 2:
                raise ValueError(f"engine.Tracker returned nodes of shape {nodes.shape}")
        extras = {
            name: float(getattr(result, name))
            for name in EFDM_EXTRAS
            if getattr(result, name, None) is not None
        }
        status = getattr(result, "status", None)
        verdict = None if status is None else str(status)
        return Step(contours[0], extras, verdict, others=tuple(contours[1:]))


def efdm_factory(options: Mapping[str, Any] | None = None) -> Factory:
    """A factory for the efdm tracker with ``TrackerOptions`` fields ``options`` (None: defaults).

    Raises
    ------
    ImportError, AttributeError
        If ``engine.Tracker`` or ``engine.tracking.PiecesTracker`` cannot be imported.
    ValueError
        If an option is unknown or out of bounds (checked now, not on the first clip).
    """
    engine = importlib.import_module("engine")
    pieces_tracker = importlib.import_module("engine.tracking").PiecesTracker
    chosen = dict(options or {})
    engine.TrackerOptions.from_mapping(chosen)

    def make(contours: Sequence[Nodes]) -> ContourTracker:
        pieces = _pieces(contours)
        if len(pieces) == 1:
            return EfdmTracker(engine.Tracker(pieces[0], closed=True, **chosen))
        return EfdmTracker(pieces_tracker(pieces, **chosen))

    return make


def factory(name: str, options: Mapping[str, Any] | None = None) -> Factory:
    """The factory of tracker ``name`` (one of :data:`TRACKERS`); ``options`` are efdm's.

    Raises
    ------
    ImportError, AttributeError
        If the tracker's library is missing (efdm: ``engine.Tracker``).
    ValueError
        If ``name`` is unknown, or an efdm option is.
    """
    if name == "efdm":
        return efdm_factory(options)
    if name == "static":
        return StaticTracker
    if name == "skimage":
        importlib.import_module("skimage.segmentation")
        return SkimageTracker
    raise ValueError(f"unknown tracker {name!r}; choose from {', '.join(TRACKERS)}")
