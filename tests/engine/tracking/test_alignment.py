"""The prediction aligned to the appearance: a translation search over p(object)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Self

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou
from engine.tracking import Maps, Prediction, Tracker
from engine.tracking.alignment import REACH, SIDE, align_to_appearance, aligned

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]


def disc_map(shape: tuple[int, int], centre: tuple[float, float], radius: float) -> F32:
    """p(object) 0.9 on a disc, 0.1 elsewhere."""
    inside = contour_to_mask(circle_nodes(centre, radius, 256), shape) > 0
    return np.where(inside, 0.9, 0.1).astype(np.float32)


def test_a_prediction_off_the_object_is_moved_onto_it() -> None:
    p = disc_map((120, 160), (86.0, 56.0), 18.0)
    shift = align_to_appearance(p, (0, 0), circle_nodes((80.0, 60.0), 18.0, 64))
    assert shift is not None
    np.testing.assert_array_equal(shift, [6.0, -4.0])


def test_the_region_origin_is_frame_coordinates() -> None:
    p = disc_map((120, 160), (86.0, 56.0), 18.0)
    nodes = circle_nodes((80.0 + 300, 60.0 + 200), 18.0, 64)
    shift = align_to_appearance(p, (300, 200), nodes)
    np.testing.assert_array_equal(shift, [6.0, -4.0])


def test_a_prediction_on_the_object_stays() -> None:
    p = disc_map((120, 160), (80.0, 60.0), 18.0)
    assert align_to_appearance(p, (0, 0), circle_nodes((80.0, 60.0), 18.0, 64)) is None


def test_no_shift_without_a_clear_gain() -> None:
    flat = np.full((120, 160), 0.5, np.float32)  # nothing tells where the object is
    assert align_to_appearance(flat, (0, 0), circle_nodes((80.0, 60.0), 18.0, 64)) is None
    # one pixel off a disc of radius 30: a shift gains about 2 x 0.8 x 60 / 2827, 0.034 a
    # pixel of the silhouette (under GAIN); the cut places such a boundary anyway
    p = disc_map((120, 160), (81.0, 60.0), 30.0)
    assert align_to_appearance(p, (0, 0), circle_nodes((80.0, 60.0), 30.0, 64)) is None


def test_the_shift_stays_within_reach() -> None:
    p = disc_map((160, 200), (120.0, 80.0), 18.0)  # 30 px away
    shift = align_to_appearance(p, (0, 0), circle_nodes((90.0, 80.0), 18.0, 64))
    assert shift is not None
    assert np.all(np.abs(shift) <= REACH)
    assert shift[0] == REACH  # as far towards the object as allowed
    far = align_to_appearance(p, (0, 0), circle_nodes((90.0, 80.0), 18.0, 64), reach=40)
    np.testing.assert_array_equal(far, [30.0, 0.0])


def test_a_large_object_is_searched_in_blocks() -> None:
    radius = 1.5 * SIDE  # a span of 3 SIDE: blocks of 3 pixels
    p = disc_map((400, 400), (206.0, 197.0), radius)
    shift = align_to_appearance(p, (0, 0), circle_nodes((200.0, 200.0), radius, 128))
    assert shift is not None
    assert np.all(shift % 3 == 0)
    np.testing.assert_allclose(shift, [6.0, -3.0], atol=1.5)


@pytest.mark.parametrize(
    "centre",
    [(20.0, 60.0), (80.0, 22.0), (145.0, 60.0)],
    ids=["left", "top", "right"],
)
def test_no_search_beyond_the_region(centre: tuple[float, float]) -> None:
    p = disc_map((120, 160), centre, 18.0)
    assert align_to_appearance(p, (0, 0), circle_nodes(centre, 18.0, 64)) is None


def test_a_tiny_silhouette_is_left_alone() -> None:
    p = disc_map((60, 60), (32.0, 30.0), 3.0)
    assert align_to_appearance(p, (0, 0), circle_nodes((30.0, 30.0), 3.0, 16)) is None


@pytest.mark.parametrize(
    ("probability", "nodes", "reach", "message"),
    [
        (np.zeros((4, 4, 3), np.float32), circle_nodes((2, 2), 1, 8), 8, "H x W"),
        (np.zeros((40, 40), np.float32), np.zeros((2, 2)), 8, "node"),
        (np.zeros((40, 40), np.float32), np.full((8, 2), np.nan), 8, "finite"),
        (np.zeros((40, 40), np.float32), circle_nodes((20, 20), 8, 16), 0, "reach"),
        (np.zeros((40, 40), np.float32), circle_nodes((20, 20), 8, 16), 2.5, "reach"),
        (np.zeros((40, 40), np.float32), circle_nodes((20, 20), 8, 16), True, "reach"),
    ],
    ids=["3-d map", "two nodes", "nan nodes", "reach 0", "reach 2.5", "reach True"],
)
def test_bad_input_is_refused(
    probability: F32, nodes: NDArray[np.float64], reach: Any, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        align_to_appearance(probability, (0, 0), nodes, reach=reach)


@pytest.mark.parametrize("gain", [-0.1, math.nan, math.inf, "0.05", None, True])
def test_a_bad_gain_is_refused(gain: Any) -> None:
    p = disc_map((120, 160), (86.0, 56.0), 18.0)
    with pytest.raises(ValueError, match="gain"):
        align_to_appearance(p, (0, 0), circle_nodes((80.0, 60.0), 18.0, 64), gain=gain)


def test_aligned_moves_the_whole_prediction_or_returns_it() -> None:
    nodes = circle_nodes((80.0, 60.0), 18.0, 64)
    matrix = np.array([[1.0, 0.0, 3.0], [0.0, 1.0, -2.0]])
    prediction = Prediction(nodes, nodes - 1.0, matrix, 0.8)
    p = disc_map((120, 160), (86.0, 56.0), 18.0)
    maps = Maps((0, 0), p, np.zeros_like(p))
    moved = aligned(prediction, maps)
    shift = np.array([6.0, -4.0])
    np.testing.assert_array_equal(moved.nodes, nodes + shift)
    np.testing.assert_array_equal(moved.rigid, nodes - 1.0 + shift)
    np.testing.assert_array_equal(moved.matrix, [[1.0, 0.0, 9.0], [0.0, 1.0, -6.0]])
    assert moved.support == 0.8
    np.testing.assert_array_equal(matrix, [[1.0, 0.0, 3.0], [0.0, 1.0, -2.0]])  # not changed
    on = Maps((0, 0), disc_map((120, 160), (80.0, 60.0), 18.0), np.zeros_like(p))
    assert aligned(prediction, on) is prediction


# --- in the tracker: a motion model that sees no motion ---------------------------------

H, W, RADIUS, SPEED = 160, 320, 24.0, 12.0


def frame(i: int) -> tuple[U8, U8]:
    """A flat orange disc moving right by SPEED a frame over textured green; frame and mask."""
    rng = np.random.default_rng(3)
    noise = cv2.GaussianBlur(rng.normal(0, 30, (H, W)), (0, 0), 2)
    background = np.stack([60 + noise, 140 + noise, 70 + 0.5 * noise], axis=-1)
    mask = contour_to_mask(circle_nodes((60.0 + SPEED * i, 80.0), RADIUS, 256), (H, W))
    image = np.where(mask[..., None] > 0, [30, 120, 240], background)
    return np.clip(image, 0, 255).astype(np.uint8), mask


class Still:
    """A motion model that always predicts no motion (its points all went astray)."""

    def reset(self) -> None:
        pass

    def predict(
        self, previous: U8, current: U8, nodes: NDArray[np.float64], **_: Any
    ) -> Prediction:
        return Prediction.still(nodes)

    def to_state(self) -> dict[str, Any]:
        return {}

    def from_state(self, state: Mapping[str, Any]) -> Self:
        return self


def test_the_tracker_moves_its_prediction_by_the_alignment(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import engine.tracking._attempt as attempt_module

    shifts: list[NDArray[np.float64]] = []

    def spy(prediction: Prediction, maps: Maps) -> Prediction:
        moved = aligned(prediction, maps)
        shifts.append(moved.nodes.mean(axis=0) - prediction.nodes.mean(axis=0))
        return moved

    monkeypatch.setattr(attempt_module, "aligned", spy)
    ious = []
    for align in (True, False):
        tracker = Tracker(
            circle_nodes((60.0, 80.0), RADIUS, 64), motion=Still(), align_prediction=align
        )
        for i in range(8):
            image, mask = frame(i)
            nodes = tracker.step(image).nodes
            ious.append(mask_iou(contour_to_mask(nodes, (H, W)), mask))
        if align:  # the prediction stays where the disc was: every frame shifts it right
            assert len(shifts) >= 7
            assert all(s[0] >= REACH - 1e-9 and abs(s[1]) <= 1 for s in shifts)
            count = len(shifts)
    assert len(shifts) == count  # off: never asked
    assert min(ious) > 0.9
