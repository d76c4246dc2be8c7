"""FlowMotion: the similarity and, within dense flow's reach, the object's own flow."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.prediction import FLOW_REACH, FlowMotion


def _grey(frame: np.ndarray) -> np.ndarray:
    return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)


def _all_weight(points: np.ndarray) -> np.ndarray:
    return np.ones(len(points))


@pytest.mark.parametrize("seed", [0, 2])
def test_a_fast_object_is_predicted_where_it_went(seed: int) -> None:
    """At about 40 px a frame the contour moves with the object and leaves no tail behind."""
    clip = make_sequence("fast_40", seed=seed, length=16)
    motion = FlowMotion(max_features=40, flow_stiffness=20.0)
    for k in range(1, len(clip.frames)):
        nodes = mask_to_contour(clip.masks[k - 1], 128)
        before, after = _grey(clip.frames[k - 1]), _grey(clip.frames[k])
        prediction = motion.predict(before, after, nodes, frame_index=k, object_weight=_all_weight)
        assert np.linalg.norm(prediction.nodes - nodes, axis=1).mean() > FLOW_REACH
        iou = mask_iou(contour_to_mask(prediction.nodes, after.shape), clip.masks[k])
        assert iou > 0.9, k


def test_tracks_an_object_moving_40_px_a_frame() -> None:
    clip = make_sequence("fast_40", seed=2, length=20)  # lagged 46 px behind at frame 15
    tracker = Tracker(mask_to_contour(clip.masks[0], 128))
    ious = []
    for frame, mask in zip(clip.frames, clip.masks, strict=True):
        nodes = tracker.step(frame).nodes
        ious.append(mask_iou(contour_to_mask(nodes, mask.shape), mask))
    assert min(ious) > 0.93
