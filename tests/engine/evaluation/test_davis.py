"""engine.evaluation: J and F as the DAVIS toolkit defines them, by hand and against its code."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.evaluation import (
    boundary_map,
    boundary_measure,
    region_similarity,
    score_sequence,
    statistics,
)


def square(shape: tuple[int, int], x: int, y: int, side: int) -> NDArray[np.uint8]:
    mask = np.zeros(shape, np.uint8)
    mask[y : y + side, x : x + side] = 255
    return mask


def toolkit_f(fg_mask: NDArray[np.bool_], gt_mask: NDArray[np.bool_]) -> float:
    """davis2017-evaluation's f_measure and _seg2bmap, as published (no void pixels)."""
    from skimage.morphology import disk

    def seg2bmap(seg: NDArray[np.bool_]) -> NDArray[np.bool_]:
        seg = seg.astype(bool)
        e, s, se = np.zeros_like(seg), np.zeros_like(seg), np.zeros_like(seg)
        e[:, :-1] = seg[:, 1:]
        s[:-1, :] = seg[1:, :]
        se[:-1, :-1] = seg[1:, 1:]
        b = seg ^ e | seg ^ s | seg ^ se
        b[-1, :] = seg[-1, :] ^ e[-1, :]
        b[:, -1] = seg[:, -1] ^ s[:, -1]
        b[-1, -1] = 0
        return b

    bound_pix = np.ceil(0.008 * np.linalg.norm(fg_mask.shape))
    fg_b, gt_b = seg2bmap(fg_mask), seg2bmap(gt_mask)
    kernel = disk(bound_pix).astype(np.uint8)  # type: ignore[no-untyped-call]
    fg_dil = cv2.dilate(fg_b.astype(np.uint8), kernel)
    gt_dil = cv2.dilate(gt_b.astype(np.uint8), kernel)
    n_fg, n_gt = np.sum(fg_b), np.sum(gt_b)
    if n_fg == 0 and n_gt > 0:
        precision, recall = 1.0, 0.0
    elif n_fg > 0 and n_gt == 0:
        precision, recall = 0.0, 1.0
    elif n_fg == 0 and n_gt == 0:
        precision, recall = 1.0, 1.0
    else:
        precision = float(np.sum(fg_b * gt_dil)) / float(n_fg)
        recall = float(np.sum(gt_b * fg_dil)) / float(n_gt)
    return 0.0 if precision + recall == 0 else 2 * precision * recall / (precision + recall)


def test_the_boundary_map_of_a_square_by_hand() -> None:
    mask = square((6, 6), 1, 1, 3)  # rows and columns 1..3
    expected = np.zeros((6, 6), bool)
    # seg2bmap marks a pixel that differs from its east, south or south-east neighbour
    expected[0, 0:4] = [True, True, True, True]
    expected[0, 0] = True
    expected[1:4, 0] = True
    expected[1:4, 3] = True
    expected[3, 1:3] = True
    np.testing.assert_array_equal(boundary_map(mask), expected)


def test_identical_masks_score_one() -> None:
    mask = square((480, 854), 300, 200, 80)
    assert region_similarity(mask, mask) == 1.0
    assert boundary_measure(mask, mask) == 1.0


def test_a_shift_within_the_tolerance_keeps_f_at_one() -> None:
    """At 480p the tolerance is ceil(0.008 * 977) = 8 px."""
    a, b = square((480, 854), 300, 200, 80), square((480, 854), 306, 200, 80)
    assert boundary_measure(a, b) == 1.0
    assert region_similarity(a, b) == pytest.approx(74 * 80 / (86 * 80))
    assert boundary_measure(a, square((480, 854), 320, 200, 80)) < 0.8


@pytest.mark.parametrize("tolerance", [-0.01, -3.0, float("nan"), float("inf"), "8", True])
def test_a_tolerance_that_is_no_distance_is_refused(tolerance: object) -> None:
    mask = square((40, 40), 10, 10, 10)
    with pytest.raises(ValueError, match="tolerance"):
        boundary_measure(mask, mask, tolerance)  # type: ignore[arg-type]


def test_a_tolerance_beyond_the_frame_is_the_whole_frame() -> None:
    """Any two boundaries are within 10^9 px of each other: F is 1, no 2-billion-px disk."""
    a, b = square((40, 40), 5, 5, 5), square((40, 40), 30, 30, 5)
    assert boundary_measure(a, b, 1e9) == 1.0
    assert boundary_measure(a, b) < 1.0


def test_empty_masks() -> None:
    empty, some = np.zeros((20, 20)), square((20, 20), 5, 5, 5)
    assert (region_similarity(empty, empty), boundary_measure(empty, empty)) == (1.0, 1.0)
    assert (region_similarity(some, empty), boundary_measure(some, empty)) == (0.0, 0.0)
    assert (region_similarity(empty, some), boundary_measure(empty, some)) == (0.0, 0.0)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 60), st.integers(0, 40), st.integers(1, 30)), max_size=4),
    st.lists(st.tuples(st.integers(0, 60), st.integers(0, 40), st.integers(1, 30)), max_size=4),
)
def test_f_agrees_with_the_toolkit(
    ours: list[tuple[int, int, int]], theirs: list[tuple[int, int, int]]
) -> None:
    a, b = np.zeros((48, 72), bool), np.zeros((48, 72), bool)
    for x, y, side in ours:
        a |= square(a.shape, x, y, side) > 0
    for x, y, side in theirs:
        b |= square(b.shape, x, y, side) > 0
    assert boundary_measure(a, b) == pytest.approx(toolkit_f(a, b), abs=1e-12)


def test_statistics_by_hand() -> None:
    values = [1, 1, 1, 1, 0, 0, 0, 0]
    # bins of the toolkit for 8 frames: [0:3], [2:5], [4:6], [5:8]
    stats = statistics(values)
    assert (stats.mean, stats.recall, stats.decay) == (0.5, 0.5, 1.0)
    assert statistics([0.2, 0.9, 0.6]).recall == pytest.approx(2 / 3)
    with pytest.raises(ValueError, match="at least one"):
        statistics([])


def test_a_sequence_is_scored_without_its_first_and_last_frame() -> None:
    truth = [square((60, 80), 10 + i, 10, 20) for i in range(6)]
    wrong = np.zeros((60, 80), np.uint8)
    predicted = [wrong, *truth[1:-1], wrong]  # only the left-out frames are wrong
    score = score_sequence(predicted, truth)
    assert score.frames == 4
    assert (score.j.mean, score.f.mean, score.j.decay) == (1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="5 predicted masks for 6"):
        score_sequence(predicted[:5], truth)
    with pytest.raises(ValueError, match="different sizes"):
        score_sequence([np.zeros((10, 10))] * 6, truth)


def test_masks_must_be_two_dimensional_and_alike() -> None:
    with pytest.raises(ValueError, match="H x W"):
        region_similarity(np.zeros((4, 4, 3)), np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match="different sizes"):
        boundary_measure(np.zeros((4, 5)), np.zeros((5, 4)))
