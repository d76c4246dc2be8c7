"""engine.geometry.fit_similarity: OpenCV's robust sampling, then the exact least-squares refit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.geometry import fit_similarity
from engine.geometry._kernels import least_squares_similarity

F64 = NDArray[np.float64]


def _moved(points: F64, matrix: F64) -> F64:
    moved: F64 = points @ matrix[:, :2].T + matrix[:, 2]
    return moved


def _similarity(scale: float, angle: float, shift: tuple[float, float]) -> F64:
    c, s = scale * np.cos(angle), scale * np.sin(angle)
    return np.array([[c, -s, shift[0]], [s, c, shift[1]]])


def _dense_least_squares(src: F64, dst: F64) -> F64:
    """The similarity by a dense solve of the 2N x 4 linear system in (a, b, tx, ty)."""
    rows = []
    for (x, y), (u, v) in zip(src, dst, strict=True):
        rows.append(([x, -y, 1.0, 0.0], u))
        rows.append(([y, x, 0.0, 1.0], v))
    a_mat = np.array([r for r, _ in rows])
    rhs = np.array([t for _, t in rows])
    a, b, tx, ty = np.linalg.lstsq(a_mat, rhs, rcond=None)[0]
    return np.array([[a, -b, tx], [b, a, ty]])


@settings(max_examples=200, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    count=st.integers(2, 60),
    scale=st.floats(0.3, 3.0),
    angle=st.floats(-np.pi, np.pi),
    noise=st.floats(0.0, 3.0),
)
def test_closed_form_equals_a_dense_least_squares_solve(
    seed: int, count: int, scale: float, angle: float, noise: float
) -> None:
    rng = np.random.default_rng(seed)
    src = rng.uniform(-50.0, 400.0, (count, 2))
    dst = _moved(src, _similarity(scale, angle, (12.0, -7.0))) + rng.normal(0.0, noise, src.shape)
    use = rng.random(count) < 0.8
    use[:2] = True  # at least two points
    fitted, ok = least_squares_similarity(src, dst, use)
    assert ok
    expected = _dense_least_squares(src[use], dst[use])
    np.testing.assert_allclose(fitted, expected, rtol=1e-9, atol=1e-7)


def test_same_inliers_as_opencv_and_its_refined_model_to_a_thousandth_of_a_pixel() -> None:
    rng = np.random.default_rng(3)
    for trial in range(40):
        src = rng.uniform(0.0, 300.0, (50, 2)).astype(np.float32)
        truth = _similarity(rng.uniform(0.8, 1.2), rng.uniform(-0.3, 0.3), (5.0, -3.0))
        dst = (_moved(src.astype(np.float64), truth) + rng.normal(0.0, 0.7, (50, 2))).astype(
            np.float32
        )
        dst[:12] += rng.uniform(-40.0, 40.0, (12, 2)).astype(np.float32)  # outliers
        for method, flag in (("ransac", cv2.RANSAC), ("lmeds", cv2.LMEDS)):
            ours, inliers = fit_similarity(src, dst, method=method, threshold=2.0, iterations=500)
            theirs, mask = cv2.estimateAffinePartial2D(
                src, dst, method=flag, ransacReprojThreshold=2.0, maxIters=500
            )
            assert ours is not None, trial
            assert theirs is not None, trial
            np.testing.assert_array_equal(inliers, mask.ravel() != 0)
            points = src.astype(np.float64)
            gap = np.abs(_moved(points, ours) - _moved(points, np.asarray(theirs, np.float64)))
            assert gap.max() < 1e-3, (trial, method, gap.max())


def test_the_fit_is_the_least_squares_optimum_of_its_inliers() -> None:
    rng = np.random.default_rng(5)
    src = rng.uniform(0.0, 200.0, (40, 2))
    dst = _moved(src, _similarity(1.1, 0.2, (3.0, 4.0))) + rng.normal(0.0, 0.5, (40, 2))
    ours, inliers = fit_similarity(src, dst, threshold=3.0)
    assert ours is not None
    assert inliers.all()

    def cost(m: F64) -> float:
        return float(((_moved(src, m) - dst) ** 2).sum())

    base = cost(ours)
    for k in range(6):  # nudging any parameter only makes it worse
        a, b, tx, ty = ours[0, 0], ours[1, 0], ours[0, 2], ours[1, 2]
        p = np.array([a, b, tx, ty])
        p[k % 4] += 1e-4 if k < 4 else -1e-4
        nudged = np.array([[p[0], -p[1], p[2]], [p[1], p[0], p[3]]])
        assert cost(nudged) > base


def test_opencv_point_layout_and_exact_motion() -> None:
    src = np.array([[[0.0, 0.0]], [[10.0, 0.0]], [[0.0, 10.0]], [[7.0, 3.0]]], np.float32)
    truth = _similarity(2.0, np.pi / 6, (1.5, -2.5))
    dst = _moved(src.reshape(-1, 2).astype(np.float64), truth).reshape(-1, 1, 2)
    ours, inliers = fit_similarity(src, dst)
    assert ours is not None
    assert inliers.all()
    np.testing.assert_allclose(ours, truth, atol=1e-9)


def test_coincident_inliers_keep_the_sampled_model() -> None:
    fitted, ok = least_squares_similarity(
        np.ones((5, 2)), np.ones((5, 2)) * 3.0, np.ones(5, dtype=bool)
    )
    assert not ok
    assert not fitted.any()
    fitted, ok = least_squares_similarity(np.ones((1, 2)), np.ones((1, 2)), np.ones(1, bool))
    assert not ok


@pytest.mark.parametrize(
    ("src", "dst", "method", "match"),
    [
        (np.zeros((4, 3)), np.zeros((4, 3)), "ransac", "matching"),
        (np.zeros((4, 2)), np.zeros((5, 2)), "ransac", "matching"),
        (np.zeros(4), np.zeros(4), "ransac", "matching"),
        (np.zeros((4, 2)), np.zeros((4, 2)), "median", "method"),
        (np.zeros((1, 2)), np.zeros((1, 2)), "ransac", "two point pairs"),
        (np.zeros((0, 2)), np.zeros((0, 2)), "lmeds", "two point pairs"),
    ],
)
def test_bad_input_is_a_value_error(src: F64, dst: F64, method: str, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        fit_similarity(src, dst, method=method)
