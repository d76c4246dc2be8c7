"""engine.geometry: contour construction, resampling, areas, crossings and masks."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray

from engine.geometry import (
    any_in_frame,
    as_nodes,
    bounding_box,
    box_outline,
    circle_nodes,
    contour_to_mask,
    extent,
    mask_iou,
    mask_to_contour,
    mask_to_contours,
    perimeter,
    polygon_area,
    resample,
    self_intersects,
)

F64 = NDArray[np.float64]

SQUARE: F64 = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]])
BOW_TIE: F64 = np.array([[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]])
TRIANGLE: F64 = np.array([[0.0, 0.0], [10.0, 0.0], [5.0, 8.0]])


def spacing(nodes: F64, *, closed: bool = True) -> F64:
    """Distances between consecutive nodes (including last -> first when closed)."""
    pts = np.vstack([nodes, nodes[:1]]) if closed else nodes
    gaps: F64 = np.hypot(*np.diff(pts, axis=0).T)
    return gaps


# --- circle_nodes ----------------------------------------------------------------------------


def test_circle_nodes_lie_on_the_circle_evenly_spaced() -> None:
    nodes = circle_nodes((40.0, 30.0), 12.5, 24)
    assert nodes.shape == (24, 2)
    assert nodes.dtype == np.float64
    np.testing.assert_allclose(np.hypot(nodes[:, 0] - 40.0, nodes[:, 1] - 30.0), 12.5)
    np.testing.assert_allclose(spacing(nodes), 2 * 12.5 * math.sin(math.pi / 24))
    np.testing.assert_allclose(nodes[0], [52.5, 30.0], atol=1e-12)


def test_circle_nodes_run_counter_clockwise_on_screen() -> None:
    # y grows downwards on screen: from the rightmost point, counter-clockwise goes up.
    nodes = circle_nodes((0.0, 0.0), 10.0, 16)
    assert nodes[1, 1] < nodes[0, 1]  # second node is above the first
    assert nodes[4, 1] == pytest.approx(-10.0)  # a quarter turn later: the top
    # Counter-clockwise on screen is clockwise in x-right, y-up axes: negative shoelace.
    expected = 0.5 * 16 * 10.0**2 * math.sin(2 * math.pi / 16)
    assert polygon_area(nodes) == pytest.approx(-expected)


@pytest.mark.parametrize(
    ("center", "radius", "count", "message"),
    [
        ((0.0, 0.0), 0.0, 8, "radius"),
        ((0.0, 0.0), -1.0, 8, "radius"),
        ((0.0, 0.0), math.nan, 8, "radius"),
        ((0.0, 0.0), math.inf, 8, "radius"),
        ((math.nan, 0.0), 5.0, 8, "center"),
        ((0.0, 0.0), 5.0, 2, "at least 3"),
        ((0.0, 0.0), 5.0, 3.7, "whole number"),
    ],
)
def test_circle_nodes_rejects_bad_arguments(
    center: tuple[float, float], radius: float, count: int, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        circle_nodes(center, radius, count)


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: resample(circle_nodes((0.0, 0.0), 5.0, 8), 2.5), "whole number"),  # type: ignore[arg-type]
        (lambda: resample(circle_nodes((0.0, 0.0), 5.0, 8), 0), "at least 1"),
        (lambda: mask_to_contour(np.pad(np.ones((5, 5)), 3), 2), "at least 3"),
        (lambda: mask_to_contours(np.pad(np.ones((5, 5)), 3), 2.5), "whole number"),  # type: ignore[arg-type]
        (lambda: box_outline([0, 0, 5, 5], 2), "at least 3"),
    ],
)
def test_node_counts_are_whole_numbers_checked_before_use(make: Any, message: str) -> None:
    """A count the kernels cannot take is a ValueError, not a numba typing error."""
    with pytest.raises(ValueError, match=message):
        make()


def test_the_area_of_no_nodes_is_nought() -> None:
    assert polygon_area(np.zeros((0, 2))) == 0.0


# --- resample --------------------------------------------------------------------------------


def test_resample_closed_is_evenly_spaced_by_arc_length() -> None:
    # A 30 x 10 rectangle (perimeter 80) with unevenly spread input nodes; 16 output nodes
    # are 5 apart along the outline and land exactly on the corners.
    nodes = np.array(
        [[0, 0], [1, 0], [2, 0], [2.5, 0], [30, 0], [30, 10], [29, 10], [0, 10], [0, 9.5]],
        dtype=np.float64,
    )
    out = resample(nodes, 16, closed=True)
    assert out.shape == (16, 2)
    np.testing.assert_allclose(out[0], [0.0, 0.0])
    np.testing.assert_allclose(spacing(out), 5.0, atol=1e-9)
    for corner in ([30.0, 0.0], [30.0, 10.0], [0.0, 10.0]):
        assert np.hypot(*(out - corner).T).min() < 1e-9


def test_resample_closed_circle_keeps_shape_and_even_spacing() -> None:
    rng = np.random.default_rng(3)
    t = np.sort(rng.uniform(0, 2 * np.pi, 200))  # uneven angular spacing
    nodes = np.stack([50 + 20 * np.cos(t), 40 + 20 * np.sin(t)], axis=1)
    out = resample(nodes, 60)
    gaps = spacing(out)
    assert gaps.std() / gaps.mean() < 0.01
    radii = np.hypot(out[:, 0] - 50, out[:, 1] - 40)
    assert np.abs(radii - 20).max() < 0.1


def test_resample_open_keeps_both_ends() -> None:
    nodes = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 20.0]])  # length 30
    out = resample(nodes, 7, closed=False)
    np.testing.assert_allclose(out[0], [0.0, 0.0])
    np.testing.assert_allclose(out[-1], [10.0, 20.0])
    np.testing.assert_allclose(spacing(out, closed=False), 5.0, atol=1e-9)
    np.testing.assert_allclose(out[2], [10.0, 0.0], atol=1e-9)


@pytest.mark.parametrize("closed", [True, False])
def test_resample_ignores_duplicate_nodes(closed: bool) -> None:
    base = circle_nodes((30.0, 30.0), 10.0, 12)
    doubled = np.repeat(base, [1, 3, 1, 1, 2, 1, 1, 1, 4, 1, 1, 1], axis=0)
    out = resample(doubled, 25, closed=closed)
    assert np.isfinite(out).all()
    np.testing.assert_allclose(out, resample(base, 25, closed=closed), atol=1e-9)


@pytest.mark.parametrize("closed", [True, False])
def test_resample_zero_length_contour_repeats_its_point(closed: bool) -> None:
    nodes = np.full((5, 2), 7.25)
    out = resample(nodes, 9, closed=closed)
    assert out.shape == (9, 2)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, np.full((9, 2), 7.25))


def numpy_resample(nodes: F64, count: int, closed: bool) -> F64:
    """The resampling as whole-array numpy calls: what the compiled loop must equal."""
    pts = np.vstack([nodes, nodes[:1]]) if closed else nodes
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    if not arc[-1] > 0:
        return np.repeat(nodes[:1], count, axis=0).astype(np.float64)
    targets = np.linspace(0.0, arc[-1], count, endpoint=not closed)
    return np.stack([np.interp(targets, arc, pts[:, 0]), np.interp(targets, arc, pts[:, 1])], 1)


@settings(max_examples=300, deadline=None)
@given(
    nodes=arrays(
        np.float64,
        st.tuples(st.integers(2, 60), st.just(2)),
        elements=st.sampled_from([0.0, 1.0, 2.5, 7.0])
        | st.floats(-1e3, 1e3, allow_nan=False, allow_subnormal=False),
    ),
    count=st.integers(1, 200),
    closed=st.booleans(),
)
def test_resample_is_the_numpy_computation_bit_for_bit(
    nodes: F64, count: int, closed: bool
) -> None:
    """Duplicates, collinear and zero-length polylines included (the few values repeat)."""
    np.testing.assert_array_equal(
        resample(nodes, count, closed=closed), numpy_resample(nodes, count, closed)
    )


@pytest.mark.parametrize("closed", [True, False])
def test_resample_of_non_finite_nodes_is_numpys(closed: bool) -> None:
    nodes = np.array([[0.0, 0.0], [np.nan, 1.0], [3.0, 4.0]])
    out = resample(nodes, 5, closed=closed)
    np.testing.assert_array_equal(out, numpy_resample(nodes, 5, closed))


# --- perimeter -------------------------------------------------------------------------------


def test_perimeter_closes_the_polygon() -> None:
    assert perimeter(SQUARE) == pytest.approx(40.0)  # the edge back to the start counts
    assert perimeter(SQUARE[::-1] + np.array([7.0, -3.0])) == pytest.approx(40.0)
    assert perimeter(circle_nodes((0.0, 0.0), 10.0, 720)) == pytest.approx(
        2 * math.pi * 10, rel=1e-4
    )
    assert perimeter(np.full((4, 2), 3.0)) == 0.0
    assert perimeter(np.zeros((0, 2))) == 0.0


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), count=st.integers(1, 700))
def test_perimeter_is_numpys_sum_of_the_edges(seed: int, count: int) -> None:
    """The compiled pass gives numpy's number, bit for bit (thresholds read it)."""
    nodes = np.random.default_rng(seed).uniform(-500.0, 500.0, (count, 2))
    closed = np.vstack([nodes, nodes[:1]])
    assert perimeter(nodes) == float(np.linalg.norm(np.diff(closed, axis=0), axis=1).sum())


def test_perimeter_of_what_is_not_points_is_refused() -> None:
    with pytest.raises(ValueError, match="N, 2"):
        perimeter(np.zeros((4, 3)))


# --- polygon_area ----------------------------------------------------------------------------


def test_polygon_area_of_square_is_signed() -> None:
    # [0,0] -> [10,0] -> [10,10] -> [0,10] is counter-clockwise in x-right, y-up axes.
    assert polygon_area(SQUARE) == pytest.approx(100.0)
    assert polygon_area(SQUARE[::-1]) == pytest.approx(-100.0)
    assert polygon_area(SQUARE + np.array([123.0, -45.0])) == pytest.approx(100.0)
    assert polygon_area(np.roll(SQUARE, 1, axis=0)) == pytest.approx(100.0)


def test_polygon_area_of_degenerate_contours_is_zero() -> None:
    assert polygon_area(np.array([[0.0, 0.0], [5.0, 5.0], [10.0, 10.0]])) == pytest.approx(0.0)
    assert polygon_area(np.full((4, 2), 3.0)) == 0.0


# --- self_intersects -------------------------------------------------------------------------


def test_self_intersects_bow_tie_square_triangle() -> None:
    assert self_intersects(BOW_TIE)
    assert self_intersects(BOW_TIE[::-1])
    assert not self_intersects(SQUARE)
    assert not self_intersects(SQUARE[::-1])
    assert not self_intersects(TRIANGLE)
    assert not self_intersects(circle_nodes((0.0, 0.0), 5.0, 64))


def test_self_intersects_open_polylines() -> None:
    # Z shape: fine when open, its closing edge would cross the diagonal.
    zed = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]])
    assert not self_intersects(zed, closed=False)
    assert self_intersects(zed, closed=True)
    # The bow tie crosses itself without its closing edge too.
    assert self_intersects(BOW_TIE, closed=False)
    assert not self_intersects(np.array([[0.0, 0.0], [5.0, 5.0], [10.0, 0.0]]), closed=False)


def test_self_intersects_star_polygon() -> None:
    t = np.arange(5) * 4 * np.pi / 5  # pentagram: every other vertex of a pentagon
    star = np.stack([np.cos(t), np.sin(t)], axis=1) * 10
    assert self_intersects(star)
    pentagon = np.stack([np.cos(t / 2), np.sin(t / 2)], axis=1) * 10
    assert not self_intersects(pentagon)


# --- contour_to_mask -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("center", "radius"), [((60.0, 50.0), 6.0), ((60.5, 50.25), 15.0), ((59.37, 50.81), 30.0)]
)
def test_contour_to_mask_area_matches_the_disc(center: tuple[float, float], radius: float) -> None:
    mask = contour_to_mask(circle_nodes(center, radius, 720), (100, 120))
    assert mask.shape == (100, 120)
    assert mask.dtype == np.uint8
    assert set(np.unique(mask).tolist()) == {0, 255}
    area = np.count_nonzero(mask)
    # every pixel the outline touches is filled (OpenCV's rasterisation): the
    # disc grows by at most about one pixel all round, and never shrinks
    assert math.pi * radius**2 <= area <= math.pi * (radius + 1.0) ** 2


def test_contour_to_mask_fills_inside_and_outline_pixels() -> None:
    # The square [10.2, 19.8]^2: centres 11..19 lie inside, and the outline
    # touches the pixels 10 and 20, which cv2.fillPoly fills too.
    a, b = 10.2, 19.8
    square = np.array([[a, a], [b, a], [b, b], [a, b]])
    mask = contour_to_mask(square, (32, 32))
    ys, xs = np.nonzero(mask)
    assert (xs.min(), xs.max(), ys.min(), ys.max()) == (10, 20, 10, 20)
    assert np.count_nonzero(mask) == 121


def test_contour_to_mask_uses_only_height_and_width() -> None:
    mask = contour_to_mask(circle_nodes((20.0, 10.0), 5.0, 32), (24, 40, 3))
    assert mask.shape == (24, 40)
    assert mask[10, 20] == 255
    assert mask[0, 0] == 0


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_contour_to_mask_is_empty_for_non_finite_nodes(bad: float) -> None:
    nodes = circle_nodes((20.0, 20.0), 8.0, 16)
    nodes[3, 1] = bad
    mask = contour_to_mask(nodes, (40, 40))
    assert mask.shape == (40, 40)
    assert not mask.any()


def test_contour_to_mask_outside_the_frame_and_huge_coordinates() -> None:
    assert not contour_to_mask(circle_nodes((-50.0, -50.0), 10.0, 16), (30, 30)).any()
    huge = circle_nodes((0.0, 0.0), 1e12, 16)  # covers the frame; must not overflow
    assert contour_to_mask(huge, (30, 30)).all()


# --- mask_to_contour -------------------------------------------------------------------------


@pytest.mark.parametrize("radius", [6.0, 15.0, 30.0])
def test_mask_to_contour_round_trip(radius: float) -> None:
    mask = contour_to_mask(circle_nodes((50.3, 40.6), radius, 360), (90, 110))
    nodes = mask_to_contour(mask, 64)
    assert nodes.shape == (64, 2)
    assert np.isfinite(nodes).all()
    assert not self_intersects(nodes)
    assert mask_iou(contour_to_mask(nodes, mask.shape), mask) > 0.97


def test_mask_to_contour_takes_the_largest_object() -> None:
    mask = np.zeros((60, 80), np.uint8)
    mask[5:10, 5:10] = 1  # small blob, non-zero but not 255
    mask[20:50, 30:70] = 7  # large one
    nodes = mask_to_contour(mask, 40)
    assert nodes[:, 0].min() >= 29.0
    assert nodes[:, 1].min() >= 19.0
    assert nodes[:, 0].max() <= 70.0
    assert nodes[:, 1].max() <= 50.0
    # outline through the outer pixel centres (29 x 39) or along their edges (30 x 40)
    assert 29 * 39 * 0.98 <= abs(polygon_area(nodes)) <= 30 * 40 * 1.02


@pytest.mark.parametrize("offset", [(0, 0), (7, 3), (120, 45)])
def test_mask_to_contour_of_a_crop_is_the_whole_masks_bit_for_bit(offset: tuple[int, int]) -> None:
    x, y = offset
    whole = contour_to_mask(circle_nodes((x + 31.3, y + 22.7), 17.0, 360), (y + 60, x + 70))
    crop = whole[y:, x:]
    np.testing.assert_array_equal(
        mask_to_contour(crop, 64, offset=offset), mask_to_contour(whole, 64)
    )


@pytest.mark.parametrize("offset", [(1.5, 2), (1, 2, 3), (True, 0), "12", (1,)])
def test_mask_to_contour_refuses_an_offset_that_is_not_two_integers(offset: Any) -> None:
    mask = contour_to_mask(circle_nodes((30.0, 20.0), 8.0, 64), (40, 60))
    with pytest.raises(ValueError, match="offset must be two whole numbers"):
        mask_to_contour(mask, 16, offset=offset)


def test_mask_to_contour_rejects_empty_and_non_2d_masks() -> None:
    with pytest.raises(ValueError, match="no object"):
        mask_to_contour(np.zeros((20, 20), np.uint8), 16)
    with pytest.raises(ValueError, match="two-dimensional"):
        mask_to_contour(np.full((20, 20, 3), 255, np.uint8), 16)
    with pytest.raises(ValueError, match="two-dimensional"):
        mask_to_contour(np.full(20, 255, np.uint8), 16)


# --- mask_iou --------------------------------------------------------------------------------


def test_mask_iou_edge_cases() -> None:
    empty = np.zeros((10, 10), np.uint8)
    left = empty.copy()
    left[:, :5] = 255
    right = empty.copy()
    right[:, 5:] = 1
    middle = empty.copy()
    middle[:, 3:8] = 255
    assert mask_iou(empty, empty) == 1.0
    assert mask_iou(left, empty) == 0.0
    assert mask_iou(empty, left) == 0.0
    assert mask_iou(left, left) == 1.0
    assert mask_iou(left, right) == 0.0
    assert mask_iou(left, middle) == pytest.approx(2 / 8)  # 20 shared of 80 pixels
    assert mask_iou(left, left > 0) == 1.0  # any non-zero value is object
    assert mask_iou(left, middle) == mask_iou(middle, left)


# --- as_nodes --------------------------------------------------------------------------------


def test_as_nodes_accepts_lists_and_integers() -> None:
    out = as_nodes([[0, 0], [1, 0], [0, 1]])
    assert out.dtype == np.float64
    assert out.shape == (3, 2)
    src = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    out = as_nodes(src)
    out[0, 0] = 99.0
    assert src[0, 0] == 0.0  # a copy


@pytest.mark.parametrize(
    ("nodes", "message"),
    [
        ([[0, 0], [1, 1]], "shape"),  # too few
        ([0.0, 1.0, 2.0, 3.0], "shape"),  # 1-D
        ([[0, 0, 0], [1, 1, 1], [2, 2, 2]], "shape"),  # (N, 3)
        (np.zeros((3, 2, 1)), "shape"),
        ([[0, 0], [1, math.nan], [2, 2]], "finite"),
        ([[0, 0], [1, math.inf], [2, 2]], "finite"),
        ([["a", "b"], ["c", "d"], ["e", "f"]], "numbers"),
        ([[0, 0], [1], [2, 2]], "numbers"),  # ragged
        (None, "shape"),
    ],
)
def test_as_nodes_rejects_malformed_contours(nodes: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        as_nodes(nodes)  # type: ignore[arg-type]


def test_as_nodes_min_count() -> None:
    assert as_nodes([[0, 0], [1, 1]], min_count=2).shape == (2, 2)
    with pytest.raises(ValueError, match="N >= 5"):
        as_nodes(np.zeros((4, 2)), min_count=5)


# --- extent ------------------------------------------------------------------------------------


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), count=st.integers(1, 300))
def test_extent_is_numpys_min_and_max(seed: int, count: int) -> None:
    nodes = np.random.default_rng(seed).uniform(-1e3, 1e3, (count, 2))
    assert extent(nodes) == (*nodes.min(axis=0), *nodes.max(axis=0))


def test_extent_of_a_nan_node_is_nan() -> None:
    assert all(np.isnan(v) for v in extent(np.array([[0.0, 1.0], [np.nan, 2.0]])))


@pytest.mark.parametrize("bad", [np.zeros((0, 2)), np.zeros((3, 3)), np.zeros(4)])
def test_extent_refuses_what_is_not_points(bad: np.ndarray) -> None:
    with pytest.raises(ValueError, match="N >= 1, 2"):
        extent(bad)


# --- bounding_box ------------------------------------------------------------------------------

BOXED = np.array([[10.2, 20.7], [30.0, 20.7], [30.0, 40.5], [10.2, 40.5]])


def test_bounding_box_grows_by_its_margins() -> None:
    # floor(10.2) - 3, floor(20.7) - 3, ceil(30.0) + 4, ceil(40.5) + 4
    assert bounding_box((100, 100), BOXED, 3, 4) == (7, 17, 34, 45)
    assert bounding_box((100, 100), BOXED, 3) == (7, 17, 33, 44)  # after defaults to before


def test_bounding_box_is_clipped_to_the_image() -> None:
    assert bounding_box((30, 25), BOXED, 15) == (0, 5, 25, 30)
    assert bounding_box((30, 25), BOXED, 15, keep_inside=False) == (0, 5, 25, 30)


def test_bounding_box_outside_the_image() -> None:
    far = BOXED + 500.0
    # kept inside: one pixel at the image's last row and column
    assert bounding_box((100, 80), far, 2) == (79, 99, 80, 100)
    # a plain clip: empty
    x0, y0, x1, y1 = bounding_box((100, 80), far, 2, keep_inside=False)
    assert x1 <= x0
    assert y1 <= y0


def test_bounding_box_region_holds_every_node() -> None:
    rng = np.random.default_rng(3)
    nodes = rng.uniform(5.0, 90.0, (40, 2))
    x0, y0, x1, y1 = bounding_box((100, 100), nodes, 0, 1)
    assert (nodes[:, 0] >= x0).all()
    assert (nodes[:, 1] >= y0).all()
    assert (np.round(nodes[:, 0]) < x1).all()
    assert (np.round(nodes[:, 1]) < y1).all()


@settings(max_examples=60, deadline=None)
@given(
    arrays(np.float64, st.tuples(st.integers(1, 40), st.just(2)), elements=st.floats(-5e6, 5e6)),
    st.integers(0, 20),
)
def test_bounding_box_is_numpys_floor_and_ceil_of_the_extremes(
    nodes: NDArray[np.float64], m: int
) -> None:
    """The compiled extremes give the box numpy's ``min``/``max`` would."""
    h = w = 10**7
    expected = (
        max(int(np.floor(nodes[:, 0].min())) - m, 0),
        max(int(np.floor(nodes[:, 1].min())) - m, 0),
        min(int(np.ceil(nodes[:, 0].max())) + m, w),
        min(int(np.ceil(nodes[:, 1].max())) + m, h),
    )
    assert bounding_box((h, w), nodes, m, keep_inside=False) == expected


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_bounding_box_refuses_empty_and_non_finite_nodes(bad: float) -> None:
    with pytest.raises(ValueError, match="empty"):
        bounding_box((10, 10), np.zeros((0, 2)), 1)
    nodes = BOXED.copy()
    nodes[2, 0] = bad
    with pytest.raises((ValueError, OverflowError)):
        bounding_box((100, 100), nodes, 1)


@settings(max_examples=60, deadline=None)
@given(arrays(np.float64, st.tuples(st.integers(3, 24), st.just(2)), elements=st.floats(-3e6, 3e6)))
def test_contour_to_mask_vertices_are_numpys_rounding(nodes: NDArray[np.float64]) -> None:
    """The compiled fixed-point vertices are ``round(clip(v) * 16)`` (half to even), as numpy."""
    from engine.geometry._kernels import fixed_point

    halves = np.round(nodes * 2.0) / 2.0  # many exact halves: the rounding's ties
    for points in (nodes, halves / 16.0):
        expected = np.round(np.clip(points, -1e6, 1e6) * 16).astype(np.int32)
        got = fixed_point(np.ascontiguousarray(points), 16, 1e6)
        np.testing.assert_array_equal(got.reshape(-1, 2), expected)


def test_any_in_frame_asks_for_a_node_inside_not_an_overlap() -> None:
    """``[x, y]`` against (height, width): a contour around the whole frame has none in it."""
    assert any_in_frame(np.array([[9.5, 4.0], [20.0, 20.0], [30.0, 4.0]]), (5, 10))
    assert not any_in_frame(np.array([[10.0, 4.0], [20.0, 20.0], [30.0, 4.0]]), (5, 10))
    assert not any_in_frame(circle_nodes((5.0, 2.5), 100.0, 16), (5, 10))
