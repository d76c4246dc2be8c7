"""engine.Tracker end to end on a moving textured disc, state, and bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from engine import Tracker
from engine.geometry import circle_nodes, contour_to_mask, mask_iou


def scene(center: tuple[float, float], shape: tuple[int, int] = (240, 320)) -> np.ndarray:
    """A reddish disc of radius 40 on a seeded textured background (BGR)."""
    rng = np.random.default_rng(3)
    background = cv2.GaussianBlur(rng.integers(120, 230, (*shape, 3), dtype=np.uint8), (0, 0), 2)
    frame = np.ascontiguousarray(background)
    c = (round(center[0] * 16), round(center[1] * 16))
    cv2.circle(frame, c, 40 * 16, (40, 50, 170), -1, lineType=cv2.LINE_AA, shift=4)
    return frame


def truth(center: tuple[float, float], shape: tuple[int, int] = (240, 320)) -> np.ndarray:
    return contour_to_mask(circle_nodes(center, 40.0, 256), shape)


def test_follows_a_translating_disc() -> None:
    centers = [(100.0 + 6 * k, 110.0 + 2.5 * k) for k in range(15)]
    tracker = Tracker(circle_nodes(centers[0], 40.0, 64))
    for k, c in enumerate(centers):
        result = tracker.step(scene(c))
        assert result.nodes.shape == (64, 2)
        assert np.isfinite(result.nodes).all()
        assert 0.0 <= result.confidence <= 1.0
        iou = mask_iou(contour_to_mask(result.nodes, (240, 320)), truth(c))
        assert iou >= 0.9, (k, iou)
    assert np.linalg.norm(result.nodes.mean(axis=0) - centers[-1]) < 2.0


def test_first_step_returns_the_given_contour() -> None:
    nodes = circle_nodes((120, 100), 40.0, 32)
    result = Tracker(nodes).step(scene((120, 100)))
    np.testing.assert_allclose(result.nodes, nodes, atol=1e-9)
    assert result.converged
    assert result.iterations == 0


def test_state_round_trip_continues_identically() -> None:
    frames = [scene((100.0 + 5 * k, 120.0)) for k in range(4)]
    a = Tracker(circle_nodes((100, 120), 40.0, 48))
    for f in frames[:2]:
        a.step(f)
    b = Tracker.from_state(json.loads(json.dumps(a.to_state())))
    for f in frames[2:]:
        np.testing.assert_allclose(a.step(f).nodes, b.step(f).nodes, atol=1e-6)


@pytest.mark.parametrize(
    "frame",
    [
        np.zeros((0, 0), np.uint8),
        np.zeros((10, 10), np.float32),
        np.zeros((10, 10, 2), np.uint8),
        "not an image",
    ],
)
def test_bad_frames_raise_value_error(frame: object) -> None:
    tracker = Tracker(circle_nodes((50, 50), 20.0, 16))
    with pytest.raises(ValueError, match="frame"):
        tracker.step(frame)  # type: ignore[arg-type]


def test_tiny_and_resized_frames_give_low_confidence_not_errors() -> None:
    tracker = Tracker(circle_nodes((100, 100), 40.0, 32))
    tracker.step(scene((100, 100)))
    tiny = tracker.step(np.zeros((1, 1, 3), np.uint8))
    assert tiny.confidence == 0.0
    assert np.isfinite(tiny.nodes).all()
    resized = tracker.step(scene((100, 100), shape=(200, 300)))
    assert np.isfinite(resized.nodes).all()


@pytest.mark.parametrize(
    ("nodes", "kwargs", "message"),
    [
        ([[1.0, 1.0]] * 5, {}, "zero length"),
        ([[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]], {}, "finite"),
        (circle_nodes((5, 5), 3.0, 8), {"closed": False}, "closed"),
        (circle_nodes((5, 5), 3.0, 8), {"bogus": 1}, "unknown tracker option"),
        (circle_nodes((5, 5), 3.0, 8), {"stiffness": -1.0}, "stiffness"),
        (circle_nodes((5, 5), 3.0, 8), {"iterations": 0}, "iterations"),
    ],
)
def test_bad_contours_and_options(nodes: object, kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Tracker(nodes, **kwargs)  # type: ignore[arg-type]


def test_malformed_state_is_a_value_error() -> None:
    with pytest.raises(ValueError, match="state"):
        Tracker.from_state({"version": 99})
    state = Tracker(circle_nodes((50, 50), 20.0, 16)).to_state()
    state["options"] = {"search_radius": "far"}
    with pytest.raises(ValueError, match="search_radius"):
        Tracker.from_state(state)


def test_many_nodes_are_supported() -> None:
    # 2000 nodes x 25 samples exceed OpenCV's 32767-point remap limit per axis.
    tracker = Tracker(circle_nodes((120, 100), 40.0, 2000))
    tracker.step(scene((120, 100)))
    result = tracker.step(scene((123, 100)))
    assert result.nodes.shape == (2000, 2)
    assert np.isfinite(result.nodes).all()


def test_results_do_not_depend_on_frame_memory_alignment() -> None:
    # The same pixels in differently aligned buffers (as decoders hand them
    # out) must track identically: REST, WebSocket and library agree exactly.
    def misaligned(frame: np.ndarray, offset: int) -> np.ndarray:
        buffer = np.empty(frame.size + 64, np.uint8)
        view = buffer[offset : offset + frame.size].reshape(frame.shape)
        view[...] = frame
        return view

    frames = [scene((100.0 + 5 * k, 120.0 + 2 * k)) for k in range(6)]
    runs = []
    for offset in (0, 1, 7):
        tracker = Tracker(circle_nodes((100, 120), 40.0, 48))
        runs.append([tracker.step(misaligned(f, offset)).nodes for f in frames])
    for run in runs[1:]:
        for a, b in zip(runs[0], run, strict=True):
            np.testing.assert_array_equal(a, b)


def test_results_do_not_depend_on_opencv_threads_and_restore_its_settings() -> None:
    frames = [scene((100.0 + 5 * k, 120.0 + 2 * k)) for k in range(6)]
    threads, ipp = cv2.getNumThreads(), cv2.ipp.useIPP()
    runs = []
    try:
        for n in (1, 2):
            cv2.setNumThreads(n)
            tracker = Tracker(circle_nodes((100, 120), 40.0, 48))
            runs.append([tracker.step(f).nodes for f in frames])
            assert cv2.ipp.useIPP() == ipp  # the tracker's own switch is undone
    finally:
        cv2.setNumThreads(threads)
    for a, b in zip(*runs, strict=True):
        np.testing.assert_array_equal(a, b)
