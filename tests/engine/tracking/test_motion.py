"""engine.tracking.motion: similarity motion between two frames (Lucas-Kanade + RANSAC)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes
from engine.tracking.motion import Motion, estimate_motion
from tests.engine.scenes import textured_frame

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

W, H = 160, 120
NODES = circle_nodes((80.0, 60.0), 25.0, 64)


@pytest.fixture(scope="module")
def grey() -> U8:
    """A textured grey frame: corners everywhere."""
    return np.asarray(cv2.cvtColor(textured_frame(3, H, W), cv2.COLOR_BGR2GRAY), np.uint8)


def warp(image: U8, matrix: F64) -> U8:
    """``image`` with its content moved by the 2 x 3 ``matrix`` (x' = A x + t)."""
    return np.asarray(
        cv2.warpAffine(
            image, matrix, (W, H), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT
        ),
        np.uint8,
    )


def transformed(matrix: F64, nodes: F64) -> F64:
    result: F64 = nodes @ matrix[:, :2].T + matrix[:, 2]
    return result


def similarity(center: tuple[float, float], degrees: float, scale: float) -> F64:
    return np.asarray(cv2.getRotationMatrix2D(center, degrees, scale), np.float64)


CASES = {
    "translation": np.array([[1.0, 0.0, 7.5], [0.0, 1.0, -4.0]]),
    "rotation+scale": similarity((80.0, 60.0), 8.0, 1.05),
    "rotation+shrink off-centre": similarity((70.0, 66.0), -12.0, 0.93),
    "sub-pixel": np.array([[1.0, 0.0, -0.4], [0.0, 1.0, 0.3]]),
}


@pytest.mark.parametrize("name", list(CASES))
def test_recovers_known_similarity_on_the_contour(grey: U8, name: str) -> None:
    matrix = CASES[name]
    motion = estimate_motion(grey, warp(grey, matrix), NODES)
    error = np.hypot(*(motion.apply(NODES) - transformed(matrix, NODES)).T)
    assert error.max() < 0.5, f"{name}: contour off by up to {error.max():.2f} px"
    assert motion.inlier_ratio > 0.5
    assert motion.points >= 3
    assert motion.matrix.shape == (2, 3)
    assert motion.matrix.dtype == np.float64


def test_still_frames_give_the_identity(grey: U8) -> None:
    motion = estimate_motion(grey, grey.copy(), NODES)
    np.testing.assert_allclose(motion.matrix, [[1, 0, 0], [0, 1, 0]], atol=0.02)
    assert motion.inlier_ratio > 0.9


@pytest.mark.parametrize("second", [90, 200])
def test_blank_frames_give_identity_without_support(second: int) -> None:
    flat = np.full((H, W), 90, np.uint8)
    motion = estimate_motion(flat, np.full((H, W), second, np.uint8), NODES)
    np.testing.assert_array_equal(motion.matrix, [[1, 0, 0], [0, 1, 0]])
    assert motion.inlier_ratio == 0.0


def test_contour_outside_the_frame_gives_identity(grey: U8) -> None:
    motion = estimate_motion(grey, grey, circle_nodes((-100.0, -100.0), 10.0, 16))
    np.testing.assert_array_equal(motion.matrix, [[1, 0, 0], [0, 1, 0]])
    assert motion.inlier_ratio == 0.0
    assert motion.points == 0


def test_contour_at_the_border_is_still_tracked(grey: U8) -> None:
    nodes = circle_nodes((8.0, 60.0), 25.0, 64)  # a third of it is off-frame
    matrix = np.array([[1.0, 0.0, 3.0], [0.0, 1.0, 2.0]])
    motion = estimate_motion(grey, warp(grey, matrix), nodes)
    visible = nodes[:, 0] >= 0
    error = np.hypot(*(motion.apply(nodes) - transformed(matrix, nodes))[visible].T)
    assert error.max() < 0.5
    assert 0.0 <= motion.inlier_ratio <= 1.0


def test_motion_apply_and_identity() -> None:
    identity = Motion.identity(5)
    assert identity.inlier_ratio == 0.0
    assert identity.points == 5
    np.testing.assert_array_equal(identity.apply(NODES), NODES)
    turn = Motion(np.array([[0.0, -1.0, 10.0], [1.0, 0.0, 20.0]]), 1.0, 3)
    np.testing.assert_allclose(turn.apply(np.array([[1.0, 2.0]])), [[8.0, 21.0]])


def test_tracked_corners_move_with_the_object_and_can_be_tracked_on(grey: U8) -> None:
    first, second = CASES["translation"], CASES["rotation+scale"]
    moved = warp(grey, first)
    motion = estimate_motion(grey, moved, NODES, max_features=40)
    assert len(motion.tracked) >= 10
    assert motion.tracked.dtype == np.float32
    # each tracked corner sits where the first motion took it: track them on
    again = warp(moved, second)
    nodes = transformed(first, NODES)
    reused = estimate_motion(moved, again, nodes, max_features=40, features=motion.tracked)
    error = np.hypot(*(reused.apply(nodes) - transformed(second, nodes)).T)
    assert error.max() < 0.5
    assert reused.points == len(nodes[::4]) + len(motion.tracked)  # no corners sought anew


def test_too_few_features_are_replaced_by_new_corners(grey: U8) -> None:
    motion = estimate_motion(
        grey, grey.copy(), NODES, max_features=40, features=np.array([[80.0, 60.0]], np.float32)
    )
    assert motion.points > len(NODES[::4]) + 1
