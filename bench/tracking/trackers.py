"""The contour trackers compared by the tracking benchmark, behind one interface.

Every tracker is constructed from the initial contour (``(N, 2)`` ``[x, y]``
nodes) and then fed the frames in order, starting with frame 0; each
:meth:`ContourTracker.step` returns the contour on that frame.

- ``"efdm"``: ``engine.Tracker`` (imported lazily: the others run without it).
- ``"static"``: the contour never moves.
- ``"skimage"``: ``skimage.segmentation.active_contour`` frame by frame,
  initialised from the previous frame's result, on the grey frame smoothed by
  ``skimage.filters.gaussian(sigma=2)``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
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
        ``(N, 2)`` ``[x, y]`` contour on this frame.
    extras : dict of str to float
        Diagnostics (efdm: iterations, converged, confidence).
    status : str or None
        The tracker's own verdict on the frame (efdm: one of :data:`STATUSES`).
    """

    nodes: Nodes
    extras: dict[str, float] = field(default_factory=dict)
    status: str | None = None


class ContourTracker(Protocol):
    """What the benchmark needs of a tracker."""

    def step(self, frame: Frame) -> Step:
        """Track into the next frame (the first call sees frame 0)."""
        ...


Factory = Callable[[Nodes], ContourTracker]


class StaticTracker:
    """The contour never moves."""

    def __init__(self, nodes: Nodes) -> None:
        self._nodes = np.array(nodes, dtype=np.float64)

    def step(self, frame: Frame) -> Step:
        """Return the initial contour whatever the frame."""
        return Step(self._nodes)


class SkimageTracker:
    """``skimage.segmentation.active_contour`` run on every frame from the last result."""

    def __init__(self, nodes: Nodes) -> None:
        from skimage.filters import gaussian
        from skimage.segmentation import active_contour

        self._gaussian: Callable[..., Any] = gaussian
        self._active_contour: Callable[..., Any] = active_contour
        self._nodes = np.array(nodes, dtype=np.float64)
        self._started = False

    def step(self, frame: Frame) -> Step:
        """Frame 0: the initial contour; later frames: the snake from the last result."""
        if not self._started:
            self._started = True
            return Step(self._nodes.copy())
        grey = frame if frame.ndim == 2 else cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        smooth = self._gaussian(grey, sigma=SKIMAGE_SIGMA)
        snake = self._active_contour(smooth, self._nodes[:, ::-1], **SKIMAGE_PARAMS)
        self._nodes = np.ascontiguousarray(np.asarray(snake, dtype=np.float64)[:, ::-1])
        return Step(self._nodes.copy())


class EfdmTracker:
    """Adapter for ``engine.Tracker`` (``step(frame)`` returns ``.nodes``, diagnostics, status)."""

    def __init__(self, engine_tracker: Any) -> None:
        self._tracker = engine_tracker

    def step(self, frame: Frame) -> Step:
        """One ``engine.Tracker.step``; its nodes, the diagnostics and the status it reports."""
        result = self._tracker.step(frame)
        nodes = np.asarray(result.nodes, dtype=np.float64)
        if nodes.ndim != 2 or nodes.shape[1] != 2:
            raise ValueError(f"engine.Tracker returned nodes of shape {nodes.shape}")
        extras = {
            name: float(getattr(result, name))
            for name in EFDM_EXTRAS
            if getattr(result, name, None) is not None
        }
        status = getattr(result, "status", None)
        return Step(nodes, extras, None if status is None else str(status))


def efdm_factory(options: Mapping[str, Any] | None = None) -> Factory:
    """A factory for the efdm tracker with ``TrackerOptions`` fields ``options`` (None: defaults).

    Raises
    ------
    ImportError, AttributeError
        If ``engine.Tracker`` cannot be imported.
    ValueError
        If an option is unknown or out of bounds (checked now, not on the first clip).
    """
    engine = importlib.import_module("engine")
    chosen = dict(options or {})
    engine.TrackerOptions.from_mapping(chosen)

    def make(nodes: Nodes) -> ContourTracker:
        tracker = engine.Tracker(np.array(nodes, dtype=np.float64), closed=True, **chosen)
        return EfdmTracker(tracker)

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
