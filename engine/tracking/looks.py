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

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from engine.tracking._state_codec import count, factors
from engine.tracking.confidence import USUAL_FRAMES
from engine.tracking.lighting import Lighting
from engine.tracking.stages import AppearanceModel, BoundaryCues, Segmentation

__all__ = ["Look"]


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
