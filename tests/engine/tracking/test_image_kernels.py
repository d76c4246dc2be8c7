"""engine.tracking._image_kernels: each fused kernel against the OpenCV or numpy it replaces."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, outward_normals
from engine.tracking import _image_kernels as kernels
from engine.tracking.appearance import Histograms, quantise
from engine.tracking.boundary import find_boundary
from engine.tracking.maps import Maps, edge_map
from tests.engine.pulls import boundary_pull
from tests.engine.scenes import DiscScene, textured_frame

F32 = NDArray[np.float32]
U8 = NDArray[np.uint8]


@pytest.mark.parametrize("channels", [1, 3])
def test_colour_lookup_is_the_table_at_each_pixels_bin(channels: int) -> None:
    frame = textured_frame(2, 37, 53)
    image = (
        frame if channels == 3 else np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)
    )
    model = Histograms.fit(frame if channels == 3 else image, circle_nodes((26, 18), 9, 24), 5)
    table = model.table()
    np.testing.assert_array_equal(model.probability(image), table[quantise(image)])


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (6, 1), (2, 2), (3, 4), (31, 45)])
def test_sobel_magnitude_matches_opencv_including_borders(shape: tuple[int, int]) -> None:
    rng = np.random.default_rng(sum(shape))
    image = (rng.random(shape) * 255).astype(np.float32)
    gx = cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3)
    expected = cv2.magnitude(gx, gy)
    np.testing.assert_allclose(kernels.sobel_magnitude(image), expected, rtol=1e-5, atol=1e-3)


def test_edge_map_is_the_scaled_clipped_gradient_of_the_smoothed_image() -> None:
    grey = np.asarray(cv2.cvtColor(textured_frame(4, 60, 80), cv2.COLOR_BGR2GRAY), np.uint8)
    smooth = cv2.GaussianBlur(grey.astype(np.float32), (0, 0), 1.0)
    mag = np.asarray(
        cv2.magnitude(cv2.Sobel(smooth, cv2.CV_32F, 1, 0), cv2.Sobel(smooth, cv2.CV_32F, 0, 1)),
        np.float32,
    )
    sample = mag[::3, ::3].ravel()
    k = int(0.95 * (sample.size - 1))
    scale = max(float(np.partition(sample, k)[k]), 32.0)
    np.testing.assert_allclose(edge_map(grey), np.minimum(mag / scale, 1.0), atol=1e-5)


def occluded_reference(
    prob: F32, inside: U8, was: U8, warp: NDArray[np.float64], low: float, high: int
) -> tuple[NDArray[np.int64], F32]:
    """The same rule with whole-array numpy (float bilinear, 128 outside)."""
    h, w = prob.shape
    padded = np.pad(was.astype(np.float64), 2, constant_values=128.0)
    rows, cols = np.indices((h, w), dtype=np.float64)
    x = warp[0, 0] * cols + warp[0, 1] * rows + warp[0, 2]
    y = warp[1, 0] * cols + warp[1, 1] * rows + warp[1, 2]
    x = np.clip(x, -1.5, was.shape[1] + 0.5)  # beyond: four border texels either way
    y = np.clip(y, -1.5, was.shape[0] + 0.5)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = x - x0, y - y0

    def at(dy: int, dx: int) -> NDArray[np.float64]:
        return np.asarray(padded[y0 + dy + 2, x0 + dx + 2], np.float64)

    top = at(0, 0) + fx * (at(0, 1) - at(0, 0))
    bottom = at(1, 0) + fx * (at(1, 1) - at(1, 0))
    level = np.floor(top + fy * (bottom - top) + 0.5)
    covered = (inside > 0) & (prob < low) & (level > high)
    where = np.flatnonzero(covered)
    return where, (level.ravel()[where] / 255.0).astype(np.float32)


@pytest.mark.parametrize("seed", range(4))
def test_occluded_matches_the_whole_array_rule(seed: int) -> None:
    rng = np.random.default_rng(seed)
    h, w = 40, 50
    prob = rng.random((h, w)).astype(np.float32)
    inside = np.zeros((h, w), np.uint8)
    inside[5:35, 8:45] = 255
    was = np.asarray(
        cv2.GaussianBlur((rng.random((30, 36)) * 255).astype(np.uint8), (5, 5), 2), np.uint8
    )
    angle = rng.uniform(-0.2, 0.2)
    warp = np.array(
        [
            [np.cos(angle), -np.sin(angle), rng.uniform(-12, 12)],
            [np.sin(angle), np.cos(angle), rng.uniform(-12, 12)],
        ]
    )
    where, value = kernels.occluded(prob, inside, was, warp, 0.35, 166)
    expected_where, expected_value = occluded_reference(prob, inside, was, warp, 0.35, 166)
    assert len(expected_where) > 0  # the case exercises the rule
    np.testing.assert_array_equal(where, expected_where)
    np.testing.assert_allclose(value, expected_value, atol=1e-7)


def test_occluded_agrees_with_opencv_warp_up_to_its_fixed_point_rounding() -> None:
    rng = np.random.default_rng(7)
    was = np.asarray(
        cv2.GaussianBlur((rng.random((70, 70)) * 255).astype(np.uint8), (7, 7), 3), np.uint8
    )
    prob = np.zeros((60, 60), np.float32)
    inside = np.full((60, 60), 255, np.uint8)
    warp = np.array([[1.0, 0.0, 3.3], [0.0, 1.0, 2.6]])  # all of it lands inside ``was``
    where, value = kernels.occluded(prob, inside, was, warp, 0.35, -1)  # every pixel
    warped = cv2.warpAffine(
        was, warp, (60, 60), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderValue=128
    )
    assert len(where) == 3600
    np.testing.assert_allclose(value * 255.0, warped.ravel().astype(np.float64), atol=1.0)


@pytest.mark.parametrize("reverse", [False, True])
def test_contour_pull_is_find_boundary_along_the_outward_normals(reverse: bool) -> None:
    scene = DiscScene(160, 120, 22.0, seed=3)
    frame = scene.frame((80.0, 60.0))
    truth = circle_nodes((80.0, 60.0), 22.0, 64)
    model = Histograms.fit(frame, truth, 12)
    grey = np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)
    maps = Maps((3, 5), model.probability(frame[5:, 3:]), edge_map(grey[5:, 3:]))
    nodes = circle_nodes((83.0, 58.0), 26.0, 48)
    if reverse:
        nodes = nodes[::-1].copy()
    normals = outward_normals(nodes)
    evidence = find_boundary(maps, nodes, normals, 9, region_weight=1.0, edge_weight=0.4)
    pull, contrast = boundary_pull(maps, nodes, 9, region_weight=1.0, edge_weight=0.4)
    np.testing.assert_allclose(pull, (evidence.strength * evidence.offset)[:, None] * normals)
    assert contrast == pytest.approx(evidence.contrast)
    assert np.abs(pull).max() > 1.0  # the off-centre circle is pulled towards the disc


def test_outward_normals_match_the_central_difference_formula() -> None:
    rng = np.random.default_rng(5)
    nodes = circle_nodes((0.0, 0.0), 10.0, 30) + rng.normal(0, 0.5, (30, 2))
    tangent = np.roll(nodes, -1, axis=0) - np.roll(nodes, 1, axis=0)
    tangent /= np.hypot(*tangent.T)[:, None]
    normal = np.stack([tangent[:, 1], -tangent[:, 0]], axis=1)
    area = 0.5 * np.sum(
        nodes[:, 0] * np.roll(nodes[:, 1], -1) - nodes[:, 1] * np.roll(nodes[:, 0], -1)
    )
    np.testing.assert_allclose(outward_normals(nodes), normal if area >= 0 else -normal, atol=1e-12)


def test_half_resolution_edges_are_sampled_where_they_belong() -> None:
    # bilinear sampling reproduces a linear ramp exactly, on either grid
    h, w = 40, 60
    prob = np.asarray(np.tile(np.linspace(0.0, 1.0, w, dtype=np.float32), (h, 1)))
    ramp_full = np.asarray(np.tile(np.arange(w, dtype=np.float32) / w, (h, 1)), np.float32)
    u = np.arange(w // 2, dtype=np.float32)
    ramp_half = np.asarray(np.tile((2.0 * u + 0.5) / w, (h // 2, 1)), dtype=np.float32)
    nodes = circle_nodes((30.0, 20.0), 9.0, 24)
    full = find_boundary(Maps((0, 0), prob, ramp_full), nodes, outward_normals(nodes), 6)
    half = find_boundary(Maps((0, 0), prob, ramp_half, 2), nodes, outward_normals(nodes), 6)
    np.testing.assert_allclose(half.offset, full.offset)
    np.testing.assert_allclose(half.strength, full.strength, atol=1e-6)


def test_maps_reject_an_unknown_edge_step() -> None:
    plane = np.zeros((4, 4), np.float32)
    with pytest.raises(ValueError, match="edge_step"):
        Maps((0, 0), plane, plane, 3)


@pytest.mark.parametrize("seed", range(3))
def test_contrast_odds_is_the_opencv_expression_bit_for_bit(seed: int) -> None:
    """The fused motion-contrast log-odds equal cv2.divide of the numpy difference and sum."""
    rng = np.random.default_rng(seed)
    differences = rng.integers(0, 256, (2, 37, 53), dtype=np.uint8)
    r_o, r_b = (np.asarray(cv2.boxFilter(d, cv2.CV_32F, (5, 5)), np.float32) for d in differences)
    expected = cv2.divide(r_b - r_o, r_b + r_o + np.float32(12.0), scale=2.0)
    np.testing.assert_array_equal(kernels.contrast_odds(r_o, r_b, 12.0, 2.0), expected)


@pytest.mark.parametrize("channels", [1, 3])
def test_taught_counts_are_the_bincounts_of_the_agreeing_pixels(channels: int) -> None:
    """One pass equals quantise, the table's verdict and two bincounts (thresholds hit exactly)."""
    rng = np.random.default_rng(channels)
    image = rng.integers(0, 256, (41, 57, channels), dtype=np.uint8)
    grey_bits, colour_bits = 5, 4
    bins = quantise(image[..., 0] if channels == 1 else image, grey_bits, colour_bits)
    n_bins = 1 << (grey_bits if channels == 1 else 3 * colour_bits)
    above, below = 0.55, 0.9
    table = rng.random(n_bins).astype(np.float32)
    table[::7] = np.float32(above)  # at the thresholds: compared in float32, as numpy does
    table[3::7] = np.float32(below)
    mask = (rng.random(image.shape[:2]) < 0.5).astype(np.uint8)
    inner = mask * (rng.random(image.shape[:2]) < 0.8).astype(np.uint8)
    outer = np.maximum(mask, (rng.random(image.shape[:2]) < 0.6).astype(np.uint8))
    ring = (outer > 0) & (mask == 0)
    for lut in (table, np.empty(0, np.float32)):
        obj, bg = kernels.taught_counts(
            image, grey_bits, colour_bits, mask, inner, outer, lut,
            np.float32(above), np.float32(below), n_bins,
        )  # fmt: skip
        inside, around = inner > 0, ring.copy()
        if len(lut):
            inside &= table[bins] > above
            around &= table[bins] < below
        np.testing.assert_array_equal(obj, np.bincount(bins[inside], minlength=n_bins))
        np.testing.assert_array_equal(bg, np.bincount(bins[around], minlength=n_bins))
