"""engine.tracking.noise.Smoothing: a noisy frame smoothed once for every tracker stepping on it."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour, mask_to_contours
from engine.testing.crowd import make_crowd
from engine.tracking import ObjectsTracker, PiecesTracker, Tracker
from engine.tracking.noise import Smoothing, denoised

U8 = NDArray[np.uint8]
SIGMA = 12.0
"""Noise (levels a channel) added to the generated frames: well past the stage's threshold."""
CROWD = make_crowd(seed=0, length=6)


def noisy(frame: U8, seed: int, sigma: float = SIGMA) -> U8:
    noise = np.random.default_rng(seed).normal(0.0, sigma, frame.shape)
    return np.asarray(np.clip(frame + noise, 0, 255), np.uint8)


def grey_of(image: U8) -> U8:
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), np.uint8)


def counting_filter(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the bilateral filter's calls (the smoothing of a whole frame)."""
    calls: list[int] = []
    bilateral = cv2.bilateralFilter

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return bilateral(*args, **kwargs)

    monkeypatch.setattr(cv2, "bilateralFilter", counted)
    return calls


def test_the_frame_is_smoothed_once_and_as_alone(monkeypatch: pytest.MonkeyPatch) -> None:
    frame = noisy(CROWD.frames[1], seed=1)
    grey = grey_of(frame)
    alone = denoised(frame, grey)
    half = np.ascontiguousarray(frame[::2, ::2])
    half_alone = denoised(half, grey_of(half))
    calls = counting_filter(monkeypatch)
    smoothing = Smoothing(frame, grey)
    with ThreadPoolExecutor(4) as pool:
        found = list(pool.map(lambda _: smoothing.of(frame, grey), range(8)))
    assert len(calls) == 1
    assert all(f is found[0] for f in found)
    assert np.array_equal(found[0], alone)
    # another frame (a tracker's own downscaled grid) is smoothed anew, not mistaken for it
    assert np.array_equal(smoothing.of(half, grey_of(half)), half_alone)
    assert len(calls) == 2


def test_a_clean_frame_is_not_smoothed(monkeypatch: pytest.MonkeyPatch) -> None:
    frame = CROWD.frames[1]
    calls = counting_filter(monkeypatch)
    assert Smoothing(frame, grey_of(frame)).of(frame, grey_of(frame)) is frame
    assert not calls


@pytest.mark.parametrize("workers", [1, 2])
def test_several_objects_smooth_a_noisy_frame_once(
    monkeypatch: pytest.MonkeyPatch, workers: int
) -> None:
    keys = (0, 3, 5)
    tracker = ObjectsTracker(
        {k: mask_to_contour(CROWD.masks[k][0], 64) for k in keys}, workers=workers
    )
    calls = counting_filter(monkeypatch)
    for t, frame in enumerate(CROWD.frames[1:], start=1):
        calls.clear()
        results = tracker.step(noisy(frame, seed=t))
        assert len(calls) == 1  # not once per object
        for k, r in zip(keys, results, strict=True):
            truth = CROWD.masks[k][t]
            assert mask_iou(contour_to_mask(r.contours[0], truth.shape), truth) > 0.85


def test_the_pieces_of_an_object_smooth_a_noisy_frame_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # two objects of the crowd as the two pieces of one
    both = np.asarray((CROWD.masks[0][0] > 0) | (CROWD.masks[3][0] > 0), np.uint8) * 255
    tracker = PiecesTracker(mask_to_contours(both, 64))
    assert len(tracker.trackers) == 2
    calls = counting_filter(monkeypatch)
    for t, frame in enumerate(CROWD.frames[1:], start=1):
        calls.clear()
        tracker.step(noisy(frame, seed=t))
        assert len(calls) == 1


def test_on_frames_tracked_downscaled_the_working_grid_is_smoothed_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # 960 x 720: each object is tracked on a 640 x 480 working grid, which is smoothed
    # once for all of them (alone, each smooths its own); the session does not smooth the
    # whole frame besides
    scale = 1.5
    frames = [
        noisy(np.asarray(cv2.resize(f, None, fx=scale, fy=scale), np.uint8), seed=t, sigma=24.0)
        for t, f in enumerate(CROWD.frames[:4])
    ]
    starts = {k: scale * mask_to_contour(CROWD.masks[k][0], 64) for k in (0, 3)}
    calls = counting_filter(monkeypatch)
    alone = [Tracker(nodes) for nodes in starts.values()]
    for frame in frames:
        for t in alone:
            t.step(frame)
    by_themselves = len(calls)
    together = ObjectsTracker(starts)
    assert by_themselves >= len(starts) * (len(frames) - 1)  # they do smooth their grids
    for frame in frames:
        calls.clear()
        together.step(frame)
        assert len(calls) == 1
