"""engine.geometry.box_outline: a box in pixel edges as a closed contour."""

from __future__ import annotations

import numpy as np
import pytest

from engine.geometry import box_outline, contour_to_mask


def test_the_outline_runs_through_the_edge_pixels_and_covers_the_box() -> None:
    nodes = box_outline([10, 20, 30, 25], 40)
    assert nodes.shape == (40, 2)
    np.testing.assert_allclose(nodes.min(axis=0), [10, 20])
    np.testing.assert_allclose(nodes.max(axis=0), [29, 24])  # the last column and row
    mask = contour_to_mask(nodes, (50, 50))
    ys, xs = np.nonzero(mask)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (10, 29, 20, 24)


def test_a_box_one_pixel_thin_still_encloses_an_area() -> None:
    nodes = box_outline([5, 5, 6, 12], 16)
    x, y = nodes[:, 0], nodes[:, 1]
    assert abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) > 1


@pytest.mark.parametrize("box", [[5, 5, 5, 9], [5, 9, 8, 2], [0, 0, float("nan"), 3]])
def test_empty_inverted_or_non_finite_boxes_are_refused(box: list[float]) -> None:
    with pytest.raises(ValueError, match="x1 > x0"):
        box_outline(box, 8)
