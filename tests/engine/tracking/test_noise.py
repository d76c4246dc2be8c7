"""engine.tracking.noise: the frame's noise measured, and smoothed out of the colours."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

import engine.tracking.tracker as tracker_module
from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.noise import (
    GRID,
    HALF_NORMAL_MEDIAN,
    LAPLACIAN_NORM,
    NOISY_FROM,
    denoised,
    noise_level,
)

U8 = NDArray[np.uint8]
RNG_SEED = 5


def with_noise(frame: U8, sigma: float, seed: int = RNG_SEED) -> U8:
    """``frame`` with independent Gaussian noise of ``sigma`` levels on every channel."""
    noise = np.random.default_rng(seed).normal(0.0, sigma, frame.shape)
    return np.asarray(np.clip(frame + noise, 0, 255), np.uint8)


def grey_of(image: U8) -> U8:
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), np.uint8)


@pytest.mark.parametrize("sigma", [4.0, 8.0, 16.0])
def test_the_noise_of_a_sloped_frame_is_measured(sigma: float) -> None:
    # a ramp across and down: the kernel does not see a plane, only the noise on it
    ys, xs = np.mgrid[0:240, 0:320]
    ramp = (60 + 0.3 * xs + 0.2 * ys).astype(np.float64)
    frame = with_noise(np.asarray(ramp, np.uint8), sigma)
    assert noise_level(frame) == pytest.approx(sigma, rel=0.1)


def test_clean_frames_measure_no_noise() -> None:
    _, xs = np.mgrid[0:240, 0:320]
    assert noise_level(np.asarray(40 + 0.5 * xs, np.uint8)) < 1.0
    assert noise_level(np.zeros((2, 50), np.uint8)) == 0.0  # too small to measure
    # edges and clutter are a minority of the points: they do not read as noise
    for condition in ("clutter", "textured", "occluder"):
        frame = make_sequence(condition, seed=0, length=2).frames[1]
        assert noise_level(grey_of(frame)) < NOISY_FROM, condition


def numpy_noise_level(grey: U8) -> float:
    """The measure as numpy states it: the lower median of the responses on the grid."""
    h, w = grey.shape
    block = np.stack(
        [
            grey[r : h - 2 + r : GRID, c : w - 2 + c : GRID].astype(np.int64)
            for r in range(3)
            for c in range(3)
        ]
    )
    kernel = np.array([1, -2, 1, -2, 4, -2, 1, -2, 1])[:, None, None]
    response = np.sort(np.abs((kernel * block).sum(axis=0)).ravel())
    return float(response[(response.size - 1) // 2]) / (HALF_NORMAL_MEDIAN * LAPLACIAN_NORM)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    height=st.integers(3, 40),
    width=st.integers(3, 40),
    kind=st.sampled_from(["uniform", "binary", "gaussian"]),
)
def test_the_compiled_measure_is_numpys(seed: int, height: int, width: int, kind: str) -> None:
    """The one-pass count gives the median numpy's responses give, extremes included (a
    checkerboard of 0 and 255 reaches the kernel's largest response)."""
    rng = np.random.default_rng(seed)
    if kind == "uniform":
        grey = rng.integers(0, 256, (height, width)).astype(np.uint8)
    elif kind == "binary":
        grey = (255 * rng.integers(0, 2, (height, width))).astype(np.uint8)
    else:
        grey = np.clip(rng.normal(128.0, 40.0, (height, width)), 0, 255).astype(np.uint8)
    assert noise_level(grey) == numpy_noise_level(grey)


def test_the_largest_response_is_counted() -> None:
    checker = (255 * (np.indices((9, 9)).sum(axis=0) % 2)).astype(np.uint8)
    assert (
        noise_level(checker)
        == numpy_noise_level(checker)
        == 2040 / (HALF_NORMAL_MEDIAN * LAPLACIAN_NORM)
    )


@pytest.mark.parametrize(
    "bad",
    [np.zeros((20, 30, 3), np.uint8), np.zeros((20, 30), np.float32), np.zeros(30, np.uint8)],
)
def test_noise_is_measured_on_a_grey_uint8_frame_only(bad: NDArray[np.generic]) -> None:
    with pytest.raises(ValueError, match="H x W uint8 grey frame"):
        noise_level(bad)  # type: ignore[arg-type]


def test_a_clean_frame_is_passed_on_itself() -> None:
    frame = make_sequence("clutter", seed=0, length=2).frames[1]
    assert denoised(frame, grey_of(frame)) is frame


def test_a_noisy_frame_is_smoothed_and_keeps_its_edge() -> None:
    clean = np.zeros((120, 160, 3), np.uint8)
    clean[:, :80] = (60, 90, 120)
    clean[:, 80:] = (160, 140, 100)
    noisy = with_noise(clean, 12.0)
    out = denoised(noisy, grey_of(noisy))
    assert out.shape == noisy.shape
    assert out.dtype == np.uint8
    assert out.flags.c_contiguous
    assert noise_level(grey_of(out)) < 0.5 * noise_level(grey_of(noisy))
    # each side is averaged with itself: the columns next to the edge keep their colours
    for column, colour in ((78, clean[0, 0]), (81, clean[0, 100])):
        mean = out[:, column].astype(np.float64).mean(axis=0)
        assert np.abs(mean - colour).max() < 6.0, (column, mean)


def _mean_iou(frames: list[U8], masks: list[U8]) -> float:
    tracker = Tracker(mask_to_contour(masks[0], 64))
    pairs = zip(frames, masks, strict=True)
    ious = [mask_iou(contour_to_mask(tracker.step(f).nodes, m.shape), m) for f, m in pairs]
    return float(np.mean(ious[1:]))


def test_a_noisy_camera_is_tracked_through_its_noise(monkeypatch: pytest.MonkeyPatch) -> None:
    clip = make_sequence("clutter", seed=1, length=20, size=(120, 160))
    frames = [with_noise(f, 20.0, seed) for seed, f in enumerate(clip.frames)]
    masks = list(clip.masks)
    smoothed = _mean_iou(frames, masks)
    monkeypatch.setattr(tracker_module, "denoised", lambda image, grey: image)
    raw = _mean_iou(frames, masks)
    assert smoothed >= 0.95
    assert smoothed > raw + 0.1  # the noise scattered the colours (0.69 when written)


def test_clean_video_is_tracked_exactly_as_without_the_stage(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    clip = make_sequence("plain", seed=2, length=8, size=(120, 160))
    start = mask_to_contour(clip.masks[0], 48)
    a = Tracker(start)
    with_stage = [a.step(f).nodes for f in clip.frames]
    monkeypatch.setattr(tracker_module, "denoised", lambda image, grey: image)
    b = Tracker(start)
    without = [b.step(f).nodes for f in clip.frames]
    for x, y in zip(with_stage, without, strict=True):
        np.testing.assert_array_equal(x, y)
