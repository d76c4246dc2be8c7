"""engine.tracking.beyond_band.bridge: the object's part beyond a thin strip, taken back."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.tracking import beyond_band
from engine.tracking.beyond_band import BRIDGE_GAP, REGROW_ABOVE, REGROW_CAP, bridge

SHAPE = (120, 200)
ROWS = slice(30, 90)  # the object: a 60-row block from column 10 to FAR_END
FAR_END = 180

Masks = tuple[NDArray[np.bool_], NDArray[np.float32], NDArray[np.bool_]]


def scene(strip: int, width: int, remembered_to: int = FAR_END) -> Masks:
    """The cut's object left of a background-looking strip, the object's colours beyond it.

    Returns the cut's object (columns 10 to ``strip``), p(object) (0.95 on the object on
    both sides of the strip, 0.05 on the strip and around) and the remembered outline's
    inside (columns 10 to ``remembered_to``).
    """
    seg = np.zeros(SHAPE, bool)
    seg[ROWS, 10:strip] = True
    p = np.full(SHAPE, 0.05, np.float32)
    p[ROWS, 10:FAR_END] = 0.95
    p[ROWS, strip : strip + width] = 0.05
    remembered = np.zeros(SHAPE, bool)
    remembered[ROWS, 10:remembered_to] = True
    return seg, p, remembered


def test_the_part_beyond_a_thin_strip_is_taken_back_with_the_strip() -> None:
    seg, p, remembered = scene(158, 6)
    grown = bridge(seg, p, remembered)
    assert grown[33:87, 166 : FAR_END - 2].all()  # the far part (its corners opened off)
    assert grown[40:80, 158:164].all()  # and the strip between, away from its ends
    assert not (grown & ~seg & ~remembered).any()  # nothing outside the outline
    assert grown[seg].all()


def test_nothing_is_taken_across_a_wide_strip() -> None:
    width = 2 * BRIDGE_GAP + 2
    seg, p, remembered = scene(FAR_END - 8 - width, width)
    assert np.array_equal(bridge(seg, p, remembered), seg)


def test_nothing_is_taken_outside_the_remembered_outline() -> None:
    seg, p, remembered = scene(158, 6, remembered_to=164)
    assert np.array_equal(bridge(seg, p, remembered), seg)


def test_a_strip_as_wide_as_a_sweeping_bar_is_crossed() -> None:
    """15 px: the generated ``occluder``'s widest bar (14 px) and its blurred edges."""
    width = 2 * BRIDGE_GAP - 1
    assert width >= 15
    seg, p, remembered = scene(FAR_END - 16 - width, width)
    grown = bridge(seg, p, remembered)
    assert grown[40:80, FAR_END - 16 : FAR_END - 2].all()
    assert grown[40:80, FAR_END - 16 - width : FAR_END - 16].all()


def test_the_strip_does_not_count_against_the_share() -> None:
    """A bar across the whole object: the strip and the part beyond it together are more
    than the share, the part beyond alone is not."""
    width = 14
    strip = FAR_END - 16 - width
    seg, p, remembered = scene(strip, width)
    beyond, object_ = 60 * 16, np.count_nonzero(seg)
    assert beyond < REGROW_CAP * object_ < beyond + 60 * width
    grown = bridge(seg, p, remembered)
    assert grown[40:80, strip : FAR_END - 2].all()


def test_nothing_is_taken_when_it_would_grow_the_object_too_much() -> None:
    seg, p, remembered = scene(60, 6)  # the far part is twice the cut's object
    assert (FAR_END - 66) > REGROW_CAP * (60 - 10)
    assert np.array_equal(bridge(seg, p, remembered), seg)


def whole_region_bridge(
    seg: NDArray[np.bool_], p: NDArray[np.float32], remembered: NDArray[np.bool_]
) -> NDArray[np.bool_]:
    """``bridge`` as its docstring says it, computed on the whole region (no box)."""
    disc, opening = beyond_band._BRIDGE_DISC, beyond_band._OPENING_DISC
    candidates = ((p > REGROW_ABOVE) & remembered & ~seg).astype(np.uint8)
    strong = np.asarray(cv2.morphologyEx(candidates, cv2.MORPH_OPEN, opening), np.uint8)
    count, labels = cv2.connectedComponents(strong, connectivity=4)
    object_ = seg.astype(np.uint8)
    touching = np.zeros(count, bool)
    touching[labels[(cv2.dilate(object_, beyond_band._CROSS) > 0) & (strong > 0)]] = True
    near = np.zeros(count, bool)
    near[labels[(cv2.dilate(cv2.dilate(object_, disc), disc) > 0) & (strong > 0)]] = True
    near[0] = False
    pieces = (near & ~touching)[labels]
    if not pieces.any():
        return seg
    joined = cv2.morphologyEx((seg | pieces).astype(np.uint8), cv2.MORPH_CLOSE, disc) > 0
    around = cv2.dilate(cv2.dilate(pieces.astype(np.uint8), disc), disc) > 0
    grown = pieces | (joined & ~seg & remembered & around)
    if np.count_nonzero(pieces) > REGROW_CAP * np.count_nonzero(seg):
        return seg
    result: NDArray[np.bool_] = seg | grown
    return result


@pytest.mark.parametrize("seed", range(4))
def test_working_in_the_loose_pieces_box_changes_nothing(seed: int) -> None:
    """Random discs split by a strip: the boxed computation equals the whole region's."""
    rng = np.random.default_rng(seed)
    bridged = 0
    for _ in range(100):
        h, w = (int(v) for v in rng.integers(40, 160, 2))
        blobs = np.zeros((h, w), np.uint8)
        p = np.full((h, w), 0.05, np.float32)
        for image, count, value in ((blobs, 3, 1), (p, 5, 0.95)):
            for _ in range(int(rng.integers(1, count + 1))):
                centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
                cv2.circle(image, centre, int(rng.integers(3, 30)), value, -1)
        p[blobs > 0] = 0.95
        x = int(rng.integers(0, w))
        strip = (x + int(rng.integers(-40, 40)), h)
        cv2.line(p, (x, 0), strip, 0.05, int(rng.integers(1, 16)))
        seg = (blobs > 0) & (p > 0.5)
        outline = np.zeros((h, w), np.uint8)
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        cv2.circle(outline, centre, int(rng.integers(10, 80)), 1, -1)
        expected = whole_region_bridge(seg, p, outline > 0)
        np.testing.assert_array_equal(bridge(seg, p, outline > 0), expected)
        bridged += not np.array_equal(expected, seg)
    assert bridged > 0  # some scenes were bridged
