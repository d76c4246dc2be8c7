"""engine.physics.matrices: the dense chain matrices."""

from __future__ import annotations

import numpy as np
import pytest

from engine import laplacian, stiffness_matrix, system_matrix


def test_closed_laplacian() -> None:
    lap = laplacian(4)
    expected = np.array([[2, -1, 0, -1], [-1, 2, -1, 0], [0, -1, 2, -1], [-1, 0, -1, 2]])
    np.testing.assert_array_equal(lap, expected)


def test_open_laplacian_has_free_ends() -> None:
    lap = laplacian(3, closed=False)
    np.testing.assert_array_equal(lap, [[1, -1, 0], [-1, 2, -1], [0, -1, 1]])
    np.testing.assert_array_equal(laplacian(2, closed=False), [[1, -1], [-1, 1]])


def test_stiffness_and_system() -> None:
    np.testing.assert_array_equal(stiffness_matrix(5, 3.0), 3.0 * laplacian(5))
    np.testing.assert_array_equal(system_matrix(5, 3.0), np.eye(5) + 3.0 * laplacian(5))


@pytest.mark.parametrize(("n", "closed"), [(2, True), (1, False), (0, True)])
def test_too_short(n: int, closed: bool) -> None:
    with pytest.raises(ValueError, match="too short"):
        laplacian(n, closed=closed)
