"""engine.geometry.nearest: the nearest of a set of points, exhaustively."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.geometry import nearest


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), queries=st.integers(0, 40), points=st.integers(1, 300))
def test_nearest_is_the_argmin_of_the_distances(seed: int, queries: int, points: int) -> None:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-50.0, 150.0, (queries, 2))
    p = rng.uniform(0.0, 100.0, (points, 2))
    found = nearest(q, p)
    assert found.shape == (queries,)
    assert found.dtype == np.int64
    distances = ((q[:, None, :] - p[None, :, :]) ** 2).sum(axis=2)
    np.testing.assert_array_equal(found, distances.argmin(axis=1))


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
