"""What a pair of frames tells every object of a session alike, measured once for all.

A session of several objects (:class:`engine.tracking.ObjectsTracker`) tracks each
object with its own :class:`~engine.tracking.Tracker`, which measures two things around
its contour that do not depend on the object: how the background moved (the camera's
motion, for the figure-ground split of the object's motion and for the motion contrast,
:mod:`engine.tracking.background`) and the dense optical flow that bends the predicted
contour (:mod:`engine.tracking.flow`).  With several objects, both are measured once over
the whole frame (the background's corners sought outside every object's silhouette) and
read by every tracker: on a whole 640 x 480 frame about 0.35 ms for the background's motion
(corners at a quarter of the resolution, tracked at half of it) and 0.5 ms for the flow.
So is the whole frame's part of the change of light (:mod:`engine.tracking.lighting`).
A tracker alone measures around its contour, as it was tuned.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.tracking.background import frame_background
from engine.tracking.flow import FlowField, dense_flow
from engine.tracking.motion import FramePair
from engine.tracking.noise import Smoothing
from engine.tracking.working import WorkingFrames

__all__ = ["Crowd", "SharedLight", "SharedMotion"]


@dataclass(frozen=True, slots=True)
class SharedLight:
    """The whole frame's part of the change of light
    (:meth:`engine.tracking.lighting.Lighting.whole`).

    Attributes
    ----------
    sample : numpy.ndarray
        (K, C) uint8: the current colour frame on the lighting's grid.
    step : numpy.ndarray or None
        (C,) float64 log ratio of the light from the previous colour frame to this one
        over the whole frame; None when not measurable.
    """

    sample: NDArray[np.uint8]
    step: NDArray[np.float64] | None


@dataclass(frozen=True, slots=True)
class SharedMotion:
    """The background's motion and the dense flow between two whole grey frames.

    Attributes
    ----------
    previous, current : numpy.ndarray
        The grey frames (H x W uint8) they were measured between.
    background : numpy.ndarray or None
        2 x 3 similarity of the background, frame ``[x, y, 1]`` of ``previous``
        to ``current``; None when the background is too flat (or too hidden) to tell.
    flow : FlowField or None
        Dense optical flow over the whole frame at half resolution (None for a
        frame under 4 pixels).
    light : SharedLight or None
        The whole frame's change of light between the two colour frames (None:
        each tracker measures its own).
    """

    previous: NDArray[np.uint8]
    current: NDArray[np.uint8]
    background: NDArray[np.float64] | None
    flow: FlowField | None
    light: SharedLight | None = None

    @classmethod
    def measure(
        cls,
        previous: NDArray[np.uint8],
        current: NDArray[np.uint8],
        excluded: NDArray[np.bool_],
        light: SharedLight | None = None,
    ) -> SharedMotion:
        """Measure both between ``previous`` and ``current``, the ``excluded`` pixels (H x W
        bool: the objects' silhouettes in ``previous``) left out of the background's fit;
        ``light`` measured by the caller between the colour frames."""
        whole = FramePair.whole(previous, current)
        halves = (whole.half_previous, whole.half_current)
        background = frame_background(previous, current, excluded, halves)
        flow = dense_flow(whole)
        return cls(previous, current, background, flow, light)

    def applies_to(self, previous: NDArray[np.uint8] | None, current: NDArray[np.uint8]) -> bool:
        """Whether these were measured between ``previous`` and ``current`` (the same
        arrays, or after a restored state, equal ones)."""
        if previous is None or current is not self.current:
            return False
        return previous is self.previous or np.array_equal(previous, self.previous)


@dataclass(frozen=True, slots=True)
class Crowd:
    """What the other objects of a session tell one tracker about a frame.

    Given by :class:`engine.tracking.ObjectsTracker` to each object's
    :meth:`engine.tracking.Tracker.step_prepared`.

    Attributes
    ----------
    covered : numpy.ndarray or None
        H x W bool: the pixels the objects in front of this one hide, where they
        were in the last frame and are in this one (:mod:`engine.tracking.covering`).
    shared : SharedMotion or None
        The whole frame's background motion and flow.
    smoothing : Smoothing or None
        The frame smoothed of its sensor noise once for all the trackers that step on it
        (:mod:`engine.tracking.noise`; None: each smooths its own).
    working : WorkingFrames or None
        The frame brought down to the working grid once for all the trackers that track
        it downscaled, each grid smoothed once (:mod:`engine.tracking.working`; None:
        each makes its own).
    """

    covered: NDArray[np.bool_] | None = None
    shared: SharedMotion | None = None
    smoothing: Smoothing | None = None
    working: WorkingFrames | None = None

    def motion_keywords(self) -> dict[str, NDArray[np.bool_] | SharedMotion]:
        """The keywords a motion model is given (only those set: a model that takes
        neither still works alone)."""
        found: dict[str, NDArray[np.bool_] | SharedMotion] = {}
        if self.covered is not None:
            found["covered"] = self.covered
        if self.shared is not None:
            found["shared"] = self.shared
        return found
