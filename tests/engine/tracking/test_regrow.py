"""engine.tracking.beyond_band.regrow: parts the contour lost, taken back beyond the band."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

import engine.tracking.beyond_band as beyond_band
from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.tracking import Tracker
from engine.tracking.beyond_band import REGROW_ABOVE, REGROW_CAP, regrow
from engine.tracking.segmentation import _signed_distance
from tests.engine.scenes import body_with_legs

BAND = 8.0
SHAPE = (120, 160)


def body() -> tuple[NDArray[np.bool_], NDArray[np.float32]]:
    """A disc as the cut's object and its signed distance (the chain's contour is its edge)."""
    inside = contour_to_mask(circle_nodes((80.0, 60.0), 30.0, 360), SHAPE)
    return inside > 0, _signed_distance((inside > 0).astype(np.uint8))


def probability_with(*boxes: tuple[int, int, int, int]) -> NDArray[np.float32]:
    """p(object): 0.95 on the disc and in each ``(x0, y0, x1, y1)`` box, 0.05 elsewhere."""
    seg, _ = body()
    p = np.where(seg, 0.95, 0.05).astype(np.float32)
    for x0, y0, x1, y1 in boxes:
        p[y0:y1, x0:x1] = 0.95
    return p


def test_a_lost_leg_beyond_the_band_is_taken_back() -> None:
    seg, distance = body()
    leg = (76, 85, 84, 118)  # 8 px wide, from inside the disc down to row 117
    seg[85:118, 76:84] |= distance[85:118, 76:84] >= -BAND  # the cut took the band's part
    grown = regrow(seg, distance, BAND, probability_with(leg))
    beyond = distance < -BAND
    expected = np.zeros(SHAPE, bool)
    expected[85:118, 76:84] = True
    expected &= beyond
    # the leg beyond the band is taken, up to the opening's rounding of its tip's corners
    assert np.count_nonzero(grown & expected) >= 0.9 * np.count_nonzero(expected)
    assert not np.any(grown & ~seg & ~expected)
    assert np.all(grown[seg])  # nothing of the object is dropped


def test_thin_strips_loose_blobs_and_leaks_are_not_taken() -> None:
    seg, distance = body()
    strip = (79, 85, 82, 118)  # 3 px wide: under the opening's disc
    assert np.array_equal(regrow(seg, distance, BAND, probability_with(strip)), seg)
    loose = (2, 2, 20, 20)  # object-like, but not touching the object
    assert np.array_equal(regrow(seg, distance, BAND, probability_with(loose)), seg)
    leak = (0, 85, 160, 120)  # the whole bottom of the frame: far more than the cap
    assert np.count_nonzero(probability_with(leak) > REGROW_ABOVE) > (1 + REGROW_CAP) * seg.sum()
    assert np.array_equal(regrow(seg, distance, BAND, probability_with(leak)), seg)


def test_within_the_band_and_on_neutral_pixels_nothing_changes() -> None:
    seg, distance = body()
    p = probability_with()
    p[distance < -BAND] = 0.5  # occluded pixels are neutral: never taken
    assert np.array_equal(regrow(seg, distance, BAND, p), seg)
    near = probability_with((0, 0, 160, 120))
    near[distance < -BAND] = 0.05  # object-like only within the band: the cut's to decide
    assert np.array_equal(regrow(seg, distance, BAND, near), seg)


def swinging_leg(steps: int) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.uint8]]]:
    """A still body with a leg that swings by 20 degrees a frame (its tip by 26 px)."""
    legs = [[-20.0 * k] for k in range(steps)]
    return body_with_legs((200, 240), (120.0, 80.0), (120, 80), legs, length=75, width=10)


def test_the_tracker_keeps_a_leg_that_swings_faster_than_the_band(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Without the regrowth the leg's far part is lost by the sixth frame; with it, kept.

    The occlusion rule is off: it takes the places the leg left (background now,
    inside the body's moved outline) for an occluder and keeps them inside the
    contour, with or without the regrowth (docs/tracking-log.md, "The failing
    synthetic conditions").
    """
    frames, masks = swinging_leg(6)

    def last_iou() -> float:
        tracker = Tracker(mask_to_contour(masks[0], 128), occlusion=False)
        for frame in frames:
            result = tracker.step(frame)
        return mask_iou(contour_to_mask(result.nodes, masks[-1].shape), masks[-1])

    with_regrowth = last_iou()
    monkeypatch.setattr(beyond_band, "REGROW_ABOVE", 1.0)  # nothing is that sure
    without = last_iou()
    assert with_regrowth >= 0.95
    assert with_regrowth > without + 0.05
