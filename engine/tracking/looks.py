"""How the object looks in each kind of frame: in colour, and in grey.

A camera that switches to its night mode sends grey frames after colour ones; a video
may fade in from black and white.  The stages that learn the object's look (the colour
models, the cue maps' memory, the band's local windows, the light's reference and the
usual look the confidence compares with) learnt it from frames of one kind, and read
frames of the other as noise: on a generated clip whose frames turned grey at the fifth,
J fell from 0.97 to 0.64 in eight frames, and the contour read ``uncertain``.

So a tracker keeps one :class:`Look` per kind.  On the first frame of the other kind the
look in use is put aside, and the other one taken up: the one put aside when the frames
last changed kind, or, the first time, one learnt from the contour the motion predicts
on that frame (as on a track's first frame).  A black frame between colour ones is grey:
the colour look waits aside, intact, and comes back with the colour.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from engine.tracking._state_codec import count, factors
from engine.tracking.confidence import USUAL_FRAMES
from engine.tracking.lighting import Lighting
from engine.tracking.stages import AppearanceModel, BoundaryCues, Segmentation

if TYPE_CHECKING:
    from engine.tracking.tracker import Tracker

__all__ = ["Look", "change_look"]


@dataclass(slots=True)
class Look:
    """The stages that learnt how the object looks in one kind of frame.

    Attributes
    ----------
    grey : bool
        The kind: grey frames (one channel, or three equal), or colour ones.
    appearance, cues, segmentation : stage
        The tracker's stages of those names (:mod:`engine.tracking.stages`).
    lighting : Lighting
        The change of light since the first frame of this kind.
    usual : numpy.ndarray
        (2,) and ``usual_count``: the usual look the confidence compares with
        (:attr:`engine.tracking.memory.Memory.usual`), as these models see it.
    usual_count : int
        Frames counted in ``usual``.
    """

    grey: bool
    appearance: AppearanceModel
    cues: BoundaryCues
    segmentation: Segmentation
    lighting: Lighting
    usual: NDArray[np.float64]
    usual_count: int

    @classmethod
    def in_use(cls, tracker: Tracker) -> Look:
        """The look ``tracker`` tracks with: its stages and light as they are (not copies)."""
        memory = tracker._memory
        return cls(
            bool(tracker._look_grey),
            tracker.appearance,
            tracker.cues,
            tracker.segmentation,
            tracker._lighting,
            memory.usual,
            memory.usual_count,
        )

    def take_up(self, tracker: Tracker) -> None:
        """Make this the look ``tracker`` tracks with."""
        tracker.appearance, tracker.cues, tracker.segmentation = (
            self.appearance,
            self.cues,
            self.segmentation,
        )
        tracker._lighting = self.lighting
        tracker._memory.usual, tracker._memory.usual_count = self.usual, self.usual_count
        tracker._look_grey = self.grey

    def to_state(self, compact: bool) -> dict[str, Any]:
        """``{"grey", "stages": {appearance, cues, segmentation}, "lighting", "usual"}``,
        JSON-able; ``compact``: the stages' compact states where they offer one."""
        stages: dict[str, Any] = {}
        for name in ("appearance", "cues", "segmentation"):
            stage = getattr(self, name)
            method = getattr(stage, "to_compact_state", None) if compact else None
            stages[name] = (method or stage.to_state)()
        return {
            "grey": self.grey,
            "stages": stages,
            "lighting": self.lighting.to_state(compact=compact),
            "usual": [float(self.usual[0]), float(self.usual[1]), self.usual_count],
        }

    @classmethod
    def from_state(
        cls,
        state: Mapping[str, Any],
        appearance: AppearanceModel,
        cues: BoundaryCues,
        segmentation: Segmentation,
    ) -> Look:
        """Inverse of :meth:`to_state`, the stages rebuilt by ``from_state`` of the given
        ones (the tracker's own, of the classes it was built with); ValueError if malformed.
        """
        if not isinstance(state, Mapping) or not isinstance(state.get("grey"), bool):
            raise ValueError("a look must be a dict with 'grey' true or false")
        stages = state["stages"]
        if not isinstance(stages, Mapping):
            raise ValueError("a look's stages must be a dict")
        usual = state["usual"]
        if not isinstance(usual, list | tuple) or len(usual) != 3:
            raise ValueError(f"a look's usual must be [inside, outside, frames]; got {usual!r}")
        frames = count(usual[2])
        if frames > USUAL_FRAMES:
            raise ValueError(f"a look's usual counts at most {USUAL_FRAMES} frames; got {frames}")
        return cls(
            state["grey"],
            appearance.from_state(stages["appearance"]),
            cues.from_state(stages["cues"]),
            segmentation.from_state(stages["segmentation"]),
            Lighting.from_state(state["lighting"]),
            factors(usual[:2], 2),
            frames,
        )


def change_look(
    tracker: Tracker, image: NDArray[np.uint8], nodes: NDArray[np.float64], grey: bool
) -> bool:
    """The first frame of another kind: the look in use put aside, the other taken up.

    Parameters
    ----------
    tracker : Tracker
        Whose look changes: its stages, light and usual look are replaced, and the one
        it tracked with is kept aside.
    image : numpy.ndarray
        The frame (its texture, for a grey frame: :mod:`engine.tracking.texture`).
    nodes : numpy.ndarray
        (N, 2) the contour the motion predicts on it, ``[x, y]`` pixels.
    grey : bool
        The frame's kind.

    Returns
    -------
    bool
        True when the look was taken up as it was put aside (the frame is then tracked
        with it as usual); False when it was learnt here on ``nodes``, as on a track's
        first frame: what was learnt from the predicted contour cannot judge it, so that
        contour is the frame's result.
    """
    leaving, aside = Look.in_use(tracker), tracker._aside
    back = aside is not None and aside.grey == grey
    if aside is not None and back:  # as it was when the frames last were of this kind
        aside.take_up(tracker)
        if tracker.options.lighting:
            tracker._lighting.resume(image, nodes)
    else:  # learnt here, as on a track's first frame
        appearance = copy.deepcopy(tracker.appearance)
        appearance.fit(image, nodes)
        lighting = Lighting()
        if tracker.options.lighting:
            lighting.start(image, nodes)
        cues, segmentation = copy.deepcopy(tracker.cues), copy.deepcopy(tracker.segmentation)
        Look(grey, appearance, cues, segmentation, lighting, np.zeros(2), 0).take_up(tracker)
    # what they remember of the last frame is of the other kind, and elsewhere
    tracker.cues.start(image, nodes, tracker.appearance)
    tracker.segmentation.start(image, nodes)
    tracker._aside = leaving
    return back
