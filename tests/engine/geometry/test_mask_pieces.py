"""engine.geometry.mask_to_contours: every piece of a mask, the largest with the full budget."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.geometry import (
    MIN_PIECE_AREA,
    circle_nodes,
    contour_to_mask,
    mask_to_contour,
    mask_to_contours,
    perimeter,
)
from engine.geometry.contours import MIN_PIECE_NODES

SHAPE = (120, 160)

discs = st.lists(
    st.tuples(
        st.floats(20.0, 140.0),  # x
        st.floats(20.0, 100.0),  # y
        st.floats(3.0, 18.0),  # radius
    ),
    min_size=1,
    max_size=4,
)


def drawn(circles: list[tuple[float, float, float]]) -> NDArray[np.uint8]:
    mask = np.zeros(SHAPE, np.uint8)
    for x, y, r in circles:
        mask |= contour_to_mask(circle_nodes((x, y), r, 90), SHAPE)
    return mask


@settings(max_examples=60, deadline=None)
@given(circles=discs, count=st.integers(8, 200))
def test_the_largest_piece_is_the_one_contour_of_the_mask(
    circles: list[tuple[float, float, float]], count: int
) -> None:
    mask = drawn(circles)
    pieces = mask_to_contours(mask, count)
    np.testing.assert_array_equal(pieces[0], mask_to_contour(mask, count))


@settings(max_examples=60, deadline=None)
@given(circles=discs, count=st.integers(8, 200))
def test_the_other_pieces_get_the_largest_ones_node_spacing(
    circles: list[tuple[float, float, float]], count: int
) -> None:
    pieces = mask_to_contours(drawn(circles), count)
    spacing = perimeter(pieces[0]) / count
    for piece in pieces[1:]:
        # resampling keeps the outline's length up to the corners it cuts
        wanted = perimeter(piece) / spacing
        assert len(piece) >= min(max(MIN_PIECE_NODES, round(0.9 * wanted) - 1), count)
        assert len(piece) <= min(max(MIN_PIECE_NODES, round(1.1 * wanted) + 1), count)


def test_a_piece_added_takes_no_node_from_the_others() -> None:
    one = drawn([(50.0, 60.0, 16.0)])
    two = drawn([(50.0, 60.0, 16.0), (120.0, 60.0, 10.0)])
    alone, together = mask_to_contours(one, 100), mask_to_contours(two, 100)
    assert len(together) == 2
    np.testing.assert_array_equal(together[0], alone[0])
    assert MIN_PIECE_NODES <= len(together[1]) < len(together[0])
    # the same spacing: about 100 * 10 / 16 nodes for the smaller disc
    assert abs(len(together[1]) - 100 * 10 / 16) <= 4


def test_a_winding_piece_gets_no_more_nodes_than_the_largest() -> None:
    mask = drawn([(40.0, 60.0, 12.0)])  # a disc of about 450 px, 75 px round
    mask[5:7, 5:155] = 255  # a 2 x 150 strip: 300 px, 300 px round
    mask[9:11, 5:155] = 255
    pieces = mask_to_contours(mask, 40)
    assert len(pieces) == 3
    assert len(pieces[0]) == 40
    assert all(len(p) == 40 for p in pieces[1:])  # four times the spacing's share, capped


def test_pieces_come_largest_first_and_small_ones_can_be_left_out() -> None:
    mask = drawn([(40.0, 40.0, 8.0), (100.0, 60.0, 15.0), (140.0, 100.0, 4.0)])
    pieces = mask_to_contours(mask, 64)
    assert [round(float(p[:, 0].mean())) for p in pieces] == [100, 40, 140]
    # the 4-pixel disc is under the tracking default, the 8-pixel one above it
    assert len(mask_to_contours(mask, 64, min_area=MIN_PIECE_AREA)) == 2
    assert len(mask_to_contours(mask, 64, min_area=1e6)) == 1  # the largest always stays


def test_bad_masks_and_counts_are_refused() -> None:
    with pytest.raises(ValueError, match="no object"):
        mask_to_contours(np.zeros(SHAPE, np.uint8), 16)
    with pytest.raises(ValueError, match="two-dimensional"):
        mask_to_contours(np.zeros((4, 4, 3), np.uint8), 16)
    with pytest.raises(ValueError, match="count"):
        mask_to_contours(drawn([(50.0, 50.0, 10.0)]), 2)
