"""engine.tracking.beyond_band.carve: background seen through a gap inside the object, left out."""

from __future__ import annotations

import cv2
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.tracking import Tracker
from engine.tracking.beyond_band import CARVE_BELOW, REGROW_CAP, carve
from engine.tracking.segmentation import _signed_distance
from tests.engine.scenes import body_with_legs

BAND = 8.0
SHAPE = (120, 160)
RADIUS = 40


def body() -> tuple[NDArray[np.bool_], NDArray[np.float32]]:
    """A disc as the cut's object and its signed distance (the chain's contour is its edge)."""
    inside = contour_to_mask(circle_nodes((80.0, 60.0), float(RADIUS), 360), SHAPE) > 0
    return inside, _signed_distance(inside.astype(np.uint8))


def probability_with(gap: NDArray[np.bool_]) -> NDArray[np.float32]:
    """p(object): 0.95 on the disc, 0.05 around it and on ``gap``."""
    seg, _ = body()
    return np.where(seg & ~gap, 0.95, 0.05).astype(np.float32)


def test_a_gap_reaching_the_background_is_left_out_through_a_narrow_mouth() -> None:
    seg, distance = body()
    # a gap opened between two limbs: 16 px wide beyond the band, 2 px wide where it
    # meets the background (the cut kept that mouth: too thin to pay for its edges)
    gap = np.zeros(SHAPE, bool)
    gap[70:96, 72:88] = True  # the gap beyond the band
    gap[96:101, 79:81] = True  # its mouth, out to the disc's edge
    p = probability_with(gap)
    carved = carve(seg, distance, BAND, p)
    assert not carved[gap & seg].any()  # all of it, mouth included
    assert np.array_equal(carved, seg & ~gap)  # and nothing else


def test_holes_thin_strips_and_gaps_within_the_band_are_kept() -> None:
    seg, distance = body()
    hole = np.zeros(SHAPE, bool)
    hole[50:70, 70:90] = True  # deep inside, not reaching the background
    assert np.array_equal(carve(seg, distance, BAND, probability_with(hole)), seg)
    strip = np.zeros(SHAPE, bool)
    strip[60:101, 79:82] = True  # reaches it, but 3 px wide: under the opening's disc
    assert np.array_equal(carve(seg, distance, BAND, probability_with(strip)), seg)
    notch = np.zeros(SHAPE, bool)
    notch[95:101, 70:90] = True  # within the band: the cut's to decide
    assert np.array_equal(carve(seg, distance, BAND, probability_with(notch)), seg)
    unsure = np.zeros(SHAPE, bool)
    unsure[70:101, 72:88] = True
    p = probability_with(unsure)
    p[unsure] = CARVE_BELOW  # not below the threshold
    assert np.array_equal(carve(seg, distance, BAND, p), seg)


def test_a_gap_larger_than_the_cap_is_not_taken() -> None:
    seg, distance = body()
    half = np.zeros(SHAPE, bool)
    half[60:101, 40:120] = True  # the disc's lower half
    assert np.count_nonzero(half & seg) > REGROW_CAP * np.count_nonzero(seg)
    assert np.array_equal(carve(seg, distance, BAND, probability_with(half)), seg)


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_carving_only_takes_out_clear_background_that_reaches_the_background(seed: int) -> None:
    """Random objects with random dark blobs: what goes is dark, reaches out, within the cap."""
    rng = np.random.default_rng(seed)
    h, w = (int(v) for v in rng.integers(40, 140, 2))
    body = np.zeros((h, w), np.uint8)
    for _ in range(int(rng.integers(1, 4))):
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        cv2.circle(body, centre, int(rng.integers(8, 50)), 1, -1)
    p = np.where(body > 0, 0.95, 0.05).astype(np.float32)
    for _ in range(int(rng.integers(0, 5))):  # gaps, holes and notches of background
        start = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        end = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        cv2.line(p, start, end, float(rng.choice([0.02, 0.3])), int(rng.integers(1, 14)))
    seg = body > 0
    distance = _signed_distance(body)
    band = float(rng.integers(2, 9))
    carved = carve(seg, distance, band, p)
    gone = seg & ~carved
    assert not np.any(carved & ~seg)  # nothing is added
    if not gone.any():
        return
    assert np.all(p[gone] < CARVE_BELOW)
    assert np.count_nonzero(gone) <= REGROW_CAP * np.count_nonzero(seg)
    count, labels = cv2.connectedComponents(gone.astype(np.uint8), connectivity=8)
    outside = cv2.dilate((~seg).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    for piece in range(1, count):
        here = labels == piece
        assert np.any(here & outside)  # each piece reaches the cut's background
        assert np.any(here & (distance > band))  # and lies partly beyond the band


def parting_legs(steps: int) -> tuple[list[NDArray[np.uint8]], list[NDArray[np.uint8]]]:
    """A still body with two legs that start as one and part by 8 degrees a frame each."""
    legs = [[-8.0 * k, 8.0 * k] for k in range(steps)]
    return body_with_legs((220, 240), (120.0, 60.0), (120, 80), legs, length=80, width=14)


def test_the_tracker_follows_the_gap_between_parting_legs() -> None:
    """Without the carving the contour spans the gap between the legs as they part (its
    worst frame 0.915); with it, 0.978.  The last frame alone tells them apart less well
    (0.930 and 0.986): by then the local colours have learnt part of the gap."""
    frames, masks = parting_legs(5)

    def worst_iou(carve_gaps: bool) -> float:
        tracker = Tracker(mask_to_contour(masks[0], 128), carve_gaps=carve_gaps)
        ious = []
        for frame, mask in zip(frames, masks, strict=True):
            nodes = tracker.step(frame).nodes
            ious.append(mask_iou(contour_to_mask(nodes, mask.shape), mask))
        return min(ious)

    assert worst_iou(True) >= 0.97
    assert worst_iou(False) < 0.95
