"""``RegionEdgeCues``: the default :class:`~engine.tracking.stages.BoundaryCues`.

The cue maps of :mod:`engine.tracking.maps` (the appearance model's object
probability and the edges) around the predicted contour, with occluders made
neutral (:mod:`engine.tracking.occlusion`); it remembers p(object) around the
contour for the next frame, both for the occlusion rule and as the weight of
the motion read at each node.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Self

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.tracking._state_codec import pack_image, pack_levels, unpack_image, unpack_levels
from engine.tracking.maps import Maps, cue_maps, roi_box
from engine.tracking.occlusion import BACKGROUND_BELOW, OBJECT_ABOVE, LocatedProbability, unoccluded
from engine.tracking.regrid import rescaled_map
from engine.tracking.stages import AppearanceModel, Frame, Grey, Move, Prediction, check_kind

__all__ = ["RegionEdgeCues"]

KIND = "region-edge-cues"


def _as_bytes(probability: NDArray[np.float32]) -> NDArray[np.uint8]:
    """p(object) as 0-255, in one pass: scale, round half to even, saturate."""
    return np.asarray(cv2.convertScaleAbs(probability, alpha=255.0), np.uint8)


class RegionEdgeCues:
    """Region and edge cue maps with an occlusion memory.

    Parameters
    ----------
    search_radius : int
        :attr:`TrackerOptions.search_radius`: the maps cover the contour's box
        grown by twice this (pixels).
    occlusion : bool
        :attr:`TrackerOptions.occlusion`: make covered pixels neutral.
    judge_front : bool, default False
        :attr:`TrackerOptions.rigid_behind`: judge the covered pieces by their
        colours (:func:`engine.tracking.occlusion.foreign`), setting the maps'
        ``in_front`` (for a prediction bent by the flow: to a rigid one it makes
        no difference).
    reveal : bool, default False
        :attr:`TrackerOptions.revealed_background`: covered pieces with the
        colours of the object's surroundings are background it uncovered, not
        covered (:func:`engine.tracking.occlusion.unoccluded`).
    """

    def __init__(
        self, search_radius: int, occlusion: bool, judge_front: bool = False, reveal: bool = False
    ) -> None:
        self.search_radius = search_radius
        self.occlusion = occlusion
        self.judge_front = judge_front
        self.reveal = reveal
        # p(object) as 0-255 around the contour in the last frame, and its origin
        self._memory: LocatedProbability | None = None

    def start(self, image: Frame, nodes: NDArray[np.float64], appearance: AppearanceModel) -> None:
        """Remember p(object) around the contour of the first frame."""
        _, (x0, y0, x1, y1) = roi_box(image.shape, nodes, self.search_radius)
        self._memory = (x0, y0), _as_bytes(appearance.probability(image[y0:y1, x0:x1]))

    def maps(
        self,
        image: Frame,
        grey: Grey,
        prediction: Prediction,
        appearance: AppearanceModel,
    ) -> Maps:
        """Cue maps around the prediction, occluders neutral; remembers p(object)."""
        maps = cue_maps(appearance.probability, image, grey, prediction.nodes, self.search_radius)
        remembered = maps
        if self.occlusion:
            silhouette = (prediction.matrix, prediction.rigid)
            # what is in front matters only to a prediction bent by the flow
            bent = not np.array_equal(prediction.nodes, prediction.rigid)
            front = self.judge_front and bent
            judge = image if front or self.reveal else None
            maps, remembered = unoccluded(
                maps, self._memory, silhouette, judge, front=front, reveal=self.reveal
            )
        self._memory = remembered.origin, _as_bytes(remembered.probability)
        return maps

    def __deepcopy__(self, memo: dict[int, Any]) -> Self:
        """A copy that shares the remembered p(object): these cues only ever replace it
        (:meth:`maps`, :meth:`rescale`), never write into it, so sharing it is as good as
        copying it, and the tracker copies its cues before every frame (should a search
        retry the frame) at a tenth of a millisecond less."""
        copied = type(self)(self.search_radius, self.occlusion, self.judge_front, self.reveal)
        copied._memory = self._memory
        return copied

    def rescale(self, move: Move, factor: float) -> None:
        """The remembered p(object) on another grid (:func:`engine.tracking.regrid.follow_size`):
        ``move`` maps old-grid ``[x, y]`` points onto it, ``factor`` its pixels per old one."""
        if self._memory is not None:
            self._memory = rescaled_map(*self._memory, move)

    def object_weight(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """p(object) in the last frame at ``[x, y]`` points (1 where unknown)."""
        if self._memory is None:
            return np.ones(len(points))
        (x0, y0), prob = self._memory
        ij = np.round(points - [x0, y0]).astype(int)
        h, w = prob.shape
        inside = (ij[:, 0] >= 0) & (ij[:, 0] < w) & (ij[:, 1] >= 0) & (ij[:, 1] < h)
        out = np.ones(len(points))
        out[inside] = prob[ij[inside, 1], ij[inside, 0]] / 255.0
        return out

    def to_state(self) -> dict[str, Any]:
        """``{"kind", "memory": {"origin", "png"} or None}``."""
        memory = None
        if self._memory is not None:
            origin, prob = self._memory
            memory = {"origin": list(origin), "png": pack_image(prob)}
        return {"kind": KIND, "memory": memory}

    def to_compact_state(self) -> dict[str, Any]:
        """:meth:`to_state` in a few kB: the remembered p(object) as three levels (clearly
        background, unsure, clearly object: what the occlusion rule asks) at half resolution."""
        memory = None
        if self._memory is not None:
            origin, prob = self._memory
            low = round(BACKGROUND_BELOW * 255)
            memory = {"origin": list(origin), **pack_levels(prob, low, OBJECT_ABOVE)}
        return {"kind": KIND, "memory": memory}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        """These cues holding ``state`` (of :meth:`to_state` or :meth:`to_compact_state`)."""
        check_kind(state, KIND, "cues")
        restored = type(self)(self.search_radius, self.occlusion, self.judge_front, self.reveal)
        memory = state.get("memory")
        if memory is not None:
            x, y = (int(v) for v in memory["origin"])
            prob = unpack_levels(memory) if "levels" in memory else unpack_image(memory["png"])
            restored._memory = (x, y), prob
        return restored
