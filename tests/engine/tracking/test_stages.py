"""engine.tracking.stages: custom motion and appearance models plugged into the Tracker.

The stages here are written the way a user would write one, in a few lines
each, without touching the Tracker: a constant-velocity motion model and a
Gaussian model of one colour difference.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, Self

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_iou
from engine.tracking import (
    AppearanceModel,
    BoundaryCues,
    ColourHistogram,
    FlowMotion,
    MotionModel,
    Prediction,
    RegionEdgeCues,
)
from engine.tracking.stages import ObjectWeight
from engine.tracking.tracker import Tracker
from tests.engine.scenes import DiscScene
from tests.engine.tracking.moving_disc import (
    T,
    assert_same,
    centre,
    check_result,
    initial,
    run,
    through_json,
)

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


class ConstantVelocity:
    """Predicts that the contour keeps the shift it made over the last frame."""

    def __init__(self) -> None:
        self.last: F64 | None = None  # the contour's centroid a frame earlier
        self.calls = 0

    def reset(self) -> None:
        self.last = None

    def predict(
        self,
        previous: U8,
        current: U8,
        nodes: F64,
        *,
        frame_index: int,
        object_weight: ObjectWeight,
    ) -> Prediction:
        self.calls += 1
        here = nodes.mean(axis=0)
        velocity = np.zeros(2) if self.last is None else here - self.last
        self.last = here
        matrix = np.array([[1.0, 0.0, velocity[0]], [0.0, 1.0, velocity[1]]])
        moved = nodes + velocity
        return Prediction(moved, moved, matrix, 1.0)

    def to_state(self) -> dict[str, Any]:
        return {"kind": "constant-velocity", "last": None if self.last is None else list(self.last)}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        if state.get("kind") != "constant-velocity":
            raise ValueError("not a constant-velocity state")
        restored = type(self)()
        last = state.get("last")
        restored.last = None if last is None else np.asarray(last, dtype=np.float64)
        return restored


class RedOverGreen:
    """Object and background as two Gaussians of red minus green."""

    def __init__(self, band: int = 12) -> None:
        self.band = band
        self.stats: list[float] | None = None  # object mean, sd; background mean, sd

    @staticmethod
    def _feature(image: U8) -> NDArray[np.float32]:
        pixels = image.astype(np.float32)
        return pixels[..., 2] - pixels[..., 1]

    def fit(self, image: U8, nodes: F64) -> None:
        mask = contour_to_mask(nodes, image.shape) > 0
        ring = cv2.dilate(mask.astype(np.uint8), np.ones((2 * self.band + 1,) * 2, np.uint8)) > 0
        value = self._feature(image)
        inside, outside = value[mask], value[ring & ~mask]
        self.stats = [
            float(inside.mean()),
            float(inside.std()) + 1.0,
            float(outside.mean()),
            float(outside.std()) + 1.0,
        ]

    def update(self, image: U8, nodes: F64) -> None:
        pass  # learns from the first frame only

    def probability(self, image: U8) -> NDArray[np.float32]:
        assert self.stats is not None
        mo, so, mb, sb = self.stats
        value = self._feature(image)
        log_ratio = (
            -0.5 * ((value - mo) / so) ** 2
            - np.log(so)
            + 0.5 * ((value - mb) / sb) ** 2
            + np.log(sb)
        )
        return np.asarray(1.0 / (1.0 + np.exp(-np.clip(log_ratio, -30, 30))), np.float32)

    def to_state(self) -> dict[str, Any]:
        return {"kind": "red-over-green", "stats": self.stats}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        if state.get("kind") != "red-over-green":
            raise ValueError("not a red-over-green state")
        restored = type(self)(self.band)
        restored.stats = None if state["stats"] is None else [float(v) for v in state["stats"]]
        return restored


def custom() -> Tracker:
    return Tracker(initial(), motion=ConstantVelocity(), appearance=RedOverGreen())


def test_the_default_stages_implement_the_protocols() -> None:
    tracker = Tracker(initial())
    assert isinstance(tracker.motion, FlowMotion)
    assert isinstance(tracker.appearance, ColourHistogram)
    assert isinstance(tracker.cues, RegionEdgeCues)
    assert isinstance(tracker.motion, MotionModel)
    assert isinstance(tracker.appearance, AppearanceModel)
    assert isinstance(tracker.cues, BoundaryCues)


def test_a_custom_motion_and_appearance_model_track_the_disc(
    scene: DiscScene, frames: list[U8]
) -> None:
    tracker = custom()
    for i, frame in enumerate(frames):
        result = tracker.step(frame)
        check_result(result)
        truth = scene.mask(centre(i))
        iou = mask_iou(contour_to_mask(result.nodes, scene.shape), truth)
        # a motion model this simple lags a frame behind, but the chain catches up
        assert iou >= 0.85, f"frame {i}: IoU {iou:.3f}"
    motion = tracker.motion
    assert isinstance(motion, ConstantVelocity)
    assert motion.calls == T - 1  # every frame after the first went through it
    assert tracker.to_state()["stages"]["appearance"]["kind"] == "red-over-green"


def test_custom_stages_change_the_track(frames: list[U8]) -> None:
    default = run(Tracker(initial()), frames[:6])
    mine = run(custom(), frames[:6])
    # the contour may end on the same pixels; what the stages saw differs
    assert any(
        not np.array_equal(a.nodes, b.nodes) or a.confidence != b.confidence
        for a, b in zip(default, mine, strict=True)
    )


def test_custom_stages_resume_exactly_from_a_state(frames: list[U8]) -> None:
    tracker = custom()
    run(tracker, frames[:6])
    state = through_json(tracker.to_state())
    assert state["stages"]["motion"] == json.loads(json.dumps(tracker.motion.to_state()))
    expected = run(tracker, frames[6:12])
    restored = Tracker.from_state(state, motion=ConstantVelocity(), appearance=RedOverGreen())
    for frame, want in zip(frames[6:12], expected, strict=True):
        assert_same(restored.step(frame), want)


def test_a_state_of_custom_stages_is_refused_by_the_defaults(frames: list[U8]) -> None:
    tracker = custom()
    run(tracker, frames[:3])
    with pytest.raises(ValueError, match="kind"):
        Tracker.from_state(through_json(tracker.to_state()))


@pytest.mark.parametrize("stage", ["motion", "appearance", "cues"])
def test_an_object_that_is_not_a_stage_is_refused(stage: str) -> None:
    with pytest.raises(ValueError, match=stage):
        Tracker(initial(), **{stage: object()})  # type: ignore[arg-type]


def test_a_copy_of_the_cues_keeps_what_they_remembered(frames: list[U8]) -> None:
    """The tracker copies its cues before a frame, should a search retry it: the copy
    shares the remembered p(object) (the cues only ever replace it), so the original's
    next frame must leave the copy's memory as it was, and the copy must make the same
    maps as the original would have."""
    import copy

    tracker = Tracker(initial())
    run(tracker, frames[:3])
    cues = tracker.cues
    assert isinstance(cues, RegionEdgeCues)
    copied = copy.deepcopy(cues)
    assert copied is not cues
    points = tracker.nodes
    before = cues.object_weight(points)
    previous, grey = (
        np.asarray(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), np.uint8) for f in frames[2:4]
    )
    weight = cues.object_weight
    prediction = tracker.motion.predict(previous, grey, points, frame_index=3, object_weight=weight)
    mine = cues.maps(frames[3], grey, prediction, tracker.appearance)
    assert not np.array_equal(cues.object_weight(points), before)  # it did remember anew
    np.testing.assert_array_equal(copied.object_weight(points), before)
    theirs = copied.maps(frames[3], grey, prediction, tracker.appearance)
    np.testing.assert_array_equal(theirs.probability, mine.probability)
    np.testing.assert_array_equal(copied.object_weight(points), cues.object_weight(points))
