"""The tracker's swappable stages: what each one must do, as ``typing.Protocol``.

:class:`engine.tracking.Tracker` runs four stages per frame and only
orchestrates them:

1. a :class:`MotionModel` predicts where the contour went (the refinement's
   rest shape X0);
2. an :class:`AppearanceModel` says how object-like each pixel is;
3. :class:`BoundaryCues` turn that and the image into the cue maps
   (:class:`engine.tracking.maps.Maps`) on which every node seeks the
   boundary, the chain holding the shape (:func:`engine.tracking.refine`);
4. a :class:`Segmentation` relabels the pixels near the refined contour
   jointly and gives the final contour (or keeps the chain's).

Each stage owns its state: ``to_state`` gives it as JSON-able data and
``from_state``, called on a stage built with the same parameters, gives a
stage holding that state (the parameters are the stage's constructor's; the
state is what it learnt from the frames).  A new stage is one class in one
file that has these methods; pass an instance to the tracker::

    tracker = Tracker(nodes, motion=MyMotion())
    resumed = Tracker.from_state(tracker.to_state(), motion=MyMotion())

A stage may also have ``to_compact_state()``: a smaller, possibly lossy state
that its ``from_state`` also reads, used by ``Tracker.to_state(compact=True)``
(the default cues keep p(object) as three levels); without it the exact state
is used there too.  The motion, cue and segmentation stages may have
``rescale(move, factor)`` (:data:`Move`): what they keep of the last frame put
on another grid, when a track follows its object's size
(:func:`engine.tracking.regrid.follow_size`); a tracker with one without it stays on
its first grid.

The defaults are :class:`engine.tracking.FlowMotion`,
:class:`engine.tracking.ColourHistogram`,
:class:`engine.tracking.RegionEdgeCues` and :class:`engine.tracking.BandCut`.
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, Self, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from engine.tracking.maps import Maps
from engine.tracking.motion import FramePair

__all__ = [
    "AppearanceModel",
    "BoundaryCues",
    "Frame",
    "Grey",
    "MotionModel",
    "Move",
    "ObjectWeight",
    "Prediction",
    "Segmentation",
    "check_kind",
]

Frame = NDArray[np.uint8]
"""An H x W x 3 BGR or H x W grey uint8 image."""

Grey = NDArray[np.uint8]
"""An H x W grey uint8 image."""

ObjectWeight = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""p(object) in the previous frame at (K, 2) ``[x, y]`` points, in [0, 1]."""

Move = Callable[[NDArray[np.float64]], NDArray[np.float64]]
"""Maps (K, 2) ``[x, y]`` points of a track's old grid onto its new one: a stage's
optional ``rescale(move, factor)`` (``factor``: new pixels per old one) keeps what it
remembers of the last frame when the track changes grid
(:func:`engine.tracking.regrid.follow_size`)."""


@dataclass(frozen=True, slots=True)
class Prediction:
    """Where a :class:`MotionModel` expects the contour in the current frame.

    Attributes
    ----------
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels: the predicted contour, the rest shape X0
        of the refinement (paper eq. 13-16 around it).
    rigid : numpy.ndarray
        (N, 2) ``[x, y]`` pixels: the previous contour moved by ``matrix``
        alone (the object's silhouette, for occlusion reasoning).
    matrix : numpy.ndarray
        2 x 3 float64 similarity mapping ``[x, y, 1]`` of the previous frame
        to the current one.
    support : float
        In [0, 1]: how well the image supported the motion (share of
        agreeing tracked points); part of the tracker's confidence.
    frames : FramePair or None
        The two grey frames cropped around the previous contour, as the motion
        was measured on them (``FramePair.around(previous, current, nodes)``):
        for the stages that measure between the same two frames (the turn), so
        that the crops and their halvings are made once; None when not made.
    """

    nodes: NDArray[np.float64]
    rigid: NDArray[np.float64]
    matrix: NDArray[np.float64]
    support: float
    frames: FramePair | None = None

    @classmethod
    def still(cls, nodes: NDArray[np.float64]) -> Prediction:
        """No motion and no support: the contour stays where it was."""
        identity = np.hstack([np.eye(2), np.zeros((2, 1))])
        return cls(nodes, nodes, identity, 0.0)


@runtime_checkable
class MotionModel(Protocol):
    """Predicts the contour's motion from one grey frame to the next."""

    def reset(self) -> None:
        """Forget what was learnt from earlier frames (a new contour was placed)."""

    def predict(
        self,
        previous: Grey,
        current: Grey,
        nodes: NDArray[np.float64],
        *,
        frame_index: int,
        object_weight: ObjectWeight,
    ) -> Prediction:
        """The contour ``nodes`` of ``previous`` moved into ``current``.

        ``frame_index`` counts the tracker's frames (``current``'s index);
        ``object_weight`` gives p(object) in the previous frame, to trust
        motion read on object pixels more than motion read on background.
        In a session of several objects (:class:`~engine.tracking.ObjectsTracker`)
        the tracker also passes ``covered=`` where other objects hide part of this
        one (H x W bool, pixels of ``previous`` they hide) and ``shared=`` (a
        :class:`~engine.tracking.shared.SharedMotion` measured once over the
        frame); a model used in such sessions takes them as keywords.
        """

    def to_state(self) -> dict[str, Any]:
        """JSON-able state (what was learnt; not the constructor's parameters)."""

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """A stage with this one's parameters holding ``state``; ValueError if malformed."""


@runtime_checkable
class AppearanceModel(Protocol):
    """Tells object pixels from background pixels."""

    def fit(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """Learn anew from the object inside the closed contour ``nodes`` of ``image``."""

    def update(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """Learn from a frame the tracker is confident about (contour ``nodes``)."""

    def probability(self, image: Frame) -> NDArray[np.float32]:
        """Per-pixel p(object) of an image or a region of one: float32 in [0, 1]."""

    def to_state(self) -> dict[str, Any]:
        """JSON-able state (what was learnt; not the constructor's parameters)."""

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """A stage with this one's parameters holding ``state``; ValueError if malformed."""


@runtime_checkable
class BoundaryCues(Protocol):
    """Makes the cue maps on which the nodes seek the object's boundary."""

    def start(self, image: Frame, nodes: NDArray[np.float64], appearance: AppearanceModel) -> None:
        """The first frame (or the first after a new contour): remember the object there."""

    def maps(
        self,
        image: Frame,
        grey: Grey,
        prediction: Prediction,
        appearance: AppearanceModel,
    ) -> Maps:
        """Cue maps of the current frame around ``prediction.nodes``.

        Also remembers what the next frame needs (its :meth:`object_weight`).
        """

    def object_weight(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """p(object) in the last frame seen at ``[x, y]`` points (1 where unknown)."""

    def to_state(self) -> dict[str, Any]:
        """JSON-able state (what was learnt; not the constructor's parameters)."""

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """A stage with this one's parameters holding ``state``; ValueError if malformed."""


@runtime_checkable
class Segmentation(Protocol):
    """Labels the pixels near the refined contour jointly; gives the final contour."""

    def start(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """The first frame (or the first after a new contour): learn the object there."""

    def learn(self, image: Frame, nodes: NDArray[np.float64]) -> None:
        """Learn from this frame's final contour."""

    def segment(
        self,
        image: Frame,
        maps: Maps,
        predicted: NDArray[np.float64],
        refined: NDArray[np.float64],
        *,
        outline: NDArray[np.float64] | None = None,
    ) -> NDArray[np.float64] | None:
        """The final (N, 2) ``[x, y]`` contour, or None to keep ``refined`` (the chain's).

        ``outline`` is the object's remembered outline moved with it (``[x, y]``
        pixels; None without the shape memory), which a stage may use as a prior.
        """

    def to_state(self) -> dict[str, Any]:
        """JSON-able state (what was learnt; not the constructor's parameters)."""

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """A stage with this one's parameters holding ``state``; ValueError if malformed."""


def check_kind(state: Mapping[str, Any], kind: str, stage: str) -> None:
    """Raise ValueError unless ``state`` is a mapping of ``{"kind": kind, ...}``.

    Each stage names its state's kind, so that a state is never restored into
    a stage of another kind (``stage`` names the stage in the message).
    """
    found = state.get("kind") if isinstance(state, Mapping) else type(state).__name__
    if found != kind:
        raise ValueError(f"{stage} state must be of kind {kind!r}; got {found!r}")
