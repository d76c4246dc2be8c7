"""engine.geometry.nearest: the nearest of a set of points, as a full scan finds it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.geometry import nearest


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), queries=st.integers(0, 40), points=st.integers(1, 700))
def test_nearest_is_the_argmin_of_the_distances(seed: int, queries: int, points: int) -> None:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-50.0, 150.0, (queries, 2))
    p = rng.uniform(0.0, 100.0, (points, 2))
    found = nearest(q, p)
    assert found.shape == (queries,)
    assert found.dtype == np.int64
    distances = ((q[:, None, :] - p[None, :, :]) ** 2).sum(axis=2)
    np.testing.assert_array_equal(found, distances.argmin(axis=1))


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), queries=st.integers(0, 40), points=st.integers(1, 700))
def test_on_a_grid_of_ties_the_answer_is_the_full_scans(
    seed: int, queries: int, points: int
) -> None:
    """Whole-pixel points repeat and lie at equal distances: the sweep in x order must
    still give the lowest index of the nearest, as reading every point does."""
    rng = np.random.default_rng(seed)
    q = rng.integers(-5, 15, (queries, 2)).astype(np.float64)
    p = rng.integers(0, 10, (points, 2)).astype(np.float64)
    distances = ((q[:, None, :] - p[None, :, :]) ** 2).sum(axis=2)
    np.testing.assert_array_equal(nearest(q, p), distances.argmin(axis=1))


def test_contour_to_contour_as_the_tracker_asks() -> None:
    """128 nodes among 512 points of a nearby ellipse: the tracker's usual question."""
    a = np.linspace(0.0, 2.0 * np.pi, 512, endpoint=False)
    dense = np.c_[300.0 + 120.0 * np.cos(a), 200.0 + 80.0 * np.sin(a)]
    b = np.linspace(0.0, 2.0 * np.pi, 128, endpoint=False) + 0.01
    nodes = np.c_[302.0 + 121.0 * np.cos(b), 199.0 + 79.0 * np.sin(b)]
    distances = ((nodes[:, None, :] - dense[None, :, :]) ** 2).sum(axis=2)
    np.testing.assert_array_equal(nearest(nodes, dense), distances.argmin(axis=1))


def test_non_finite_points_never_win() -> None:
    """A NaN point is never the nearest of a finite query, and an infinite query, no
    distance of which is finite, gets index 0: what a full scan's strict comparisons give."""
    for count in (40, 400):  # read in full, and swept
        p = np.array([[np.nan, 0.0]] + [[float(i), 0.0] for i in range(1, count)])
        q = np.array([[0.0, 0.0], [np.inf, 0.0], [20.2, 1.0]])
        assert nearest(q, p).tolist() == [1, 0, 20]


def test_ties_go_to_the_lowest_index() -> None:
    points = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]])
    assert nearest(np.zeros((1, 2)), points).tolist() == [0]


@pytest.mark.parametrize(
    ("queries", "points", "message"),
    [
        (np.zeros((3, 3)), np.zeros((2, 2)), "queries must be"),
        (np.zeros((3, 2)), np.zeros(4), "points must be"),
        (np.zeros((3, 2)), np.zeros((0, 2)), "points is empty"),
    ],
)
def test_bad_input_is_a_clear_error(queries: np.ndarray, points: np.ndarray, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        nearest(queries, points)
