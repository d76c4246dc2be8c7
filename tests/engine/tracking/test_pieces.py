"""engine.tracking.PiecesTracker: one object in two separate pieces, each held by its chain."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import mask_iou, mask_to_contours
from engine.tracking import PiecesTracker
from tests.engine.scenes import BACKGROUND_BGR, OBJECT_BGR, disc_mask, texture

U8 = NDArray[np.uint8]
W, H, T = 320, 240, 16
PIECES = (((100.0, 110.0), 40.0), ((215.0, 125.0), 30.0))  # centre, radius on frame 0
STEP = (3.0, 1.0)  # both move together, px per frame
BACKGROUND = np.asarray(BACKGROUND_BGR, np.float32) + 90.0 * texture(7, H, W)
OBJECT = np.asarray(OBJECT_BGR, np.float32) + 60.0 * texture(8, H, W)


def mask(i: int) -> U8:
    out = np.zeros((H, W), np.uint8)
    for (cx, cy), r in PIECES:
        out |= disc_mask((cx + STEP[0] * i, cy + STEP[1] * i), r, (H, W))
    return out


def frame(i: int) -> U8:
    import cv2

    inside = mask(i) > 0
    move = np.array([[1.0, 0.0, STEP[0] * i], [0.0, 1.0, STEP[1] * i]])
    shift = cv2.warpAffine(
        OBJECT, move, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
    )
    img = BACKGROUND.copy()
    img[inside] = shift[inside]
    return np.asarray(np.clip(img, 0, 255), np.uint8)


def union(contours: list[NDArray[np.float64]]) -> U8:
    from engine.geometry import contour_to_mask

    out = np.zeros((H, W), np.uint8)
    for c in contours:
        out |= contour_to_mask(c, (H, W))
    return out


def test_two_pieces_moving_together_are_followed_as_one_object() -> None:
    contours = mask_to_contours(mask(0), 128)
    assert len(contours) == 2
    tracker = PiecesTracker(contours)
    ious = []
    for i in range(T):
        result = tracker.step(frame(i))
        assert len(result.contours) == 2
        assert result.status in {"tracking", "uncertain", "lost"}
        assert 0.0 <= result.confidence <= 1.0
        ious.append(mask_iou(union(result.contours), mask(i)))
    assert np.mean(ious[1:]) >= 0.9
    assert min(ious[1:]) >= 0.8
    assert result.status == "tracking"


def test_a_pieces_state_resumes_exactly() -> None:
    tracker = PiecesTracker(mask_to_contours(mask(0), 96))
    for i in range(4):
        tracker.step(frame(i))
    resumed = PiecesTracker.from_state(json.loads(json.dumps(tracker.to_state())))
    for i in range(4, 7):
        a, b = tracker.step(frame(i)), resumed.step(frame(i))
        for x, y in zip(a.contours, b.contours, strict=True):
            np.testing.assert_array_equal(x, y)
        assert a.confidence == b.confidence


def test_nodes_are_shared_by_perimeter_and_small_pieces_can_be_left_out() -> None:
    contours = mask_to_contours(mask(0), 120)
    assert len(contours[0]) > len(contours[1]) >= 16  # the larger disc first, more nodes
    specks = mask(0).copy()
    specks[230:232, 5:7] = 255  # a 4-pixel speck
    assert len(mask_to_contours(specks, 120)) == 3
    assert len(mask_to_contours(specks, 120, min_area=10)) == 2


@pytest.mark.parametrize(
    "state", [{}, {"kind": "pieces"}, {"kind": "pieces", "pieces": []}, {"kind": "other"}, []]
)
def test_malformed_pieces_states_are_refused(state: object) -> None:
    with pytest.raises(ValueError, match="pieces"):
        PiecesTracker.from_state(state)  # type: ignore[arg-type]


def test_no_piece_is_refused() -> None:
    with pytest.raises(ValueError, match="at least one piece"):
        PiecesTracker([])
    with pytest.raises(ValueError, match="count"):
        mask_to_contours(mask(0), 2)
    with pytest.raises(ValueError, match="no object"):
        mask_to_contours(np.zeros((5, 5)), 10)
