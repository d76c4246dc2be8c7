"""The tracker tests' scene: a textured disc moving in a straight line, and result checks."""

from __future__ import annotations

import json
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine import TrackResult
from engine.geometry import circle_nodes
from engine.tracking.tracker import Tracker

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

W, H, R = 200, 120, 20.0  # frame and disc size
N = 64  # contour nodes
T = 20  # frames
SPEED = 6.0  # pixels per frame
DIRECTION = (0.96, 0.28)  # unit vector
START = (34.3, 36.7)


def centre(i: int) -> tuple[float, float]:
    """Where the disc is on frame ``i``."""
    return START[0] + SPEED * DIRECTION[0] * i, START[1] + SPEED * DIRECTION[1] * i


def initial() -> F64:
    return circle_nodes(centre(0), R, N)


def check_result(result: TrackResult, count: int = N) -> None:
    """The invariants every step must keep."""
    assert isinstance(result, TrackResult)
    assert result.nodes.shape == (count, 2)
    assert result.nodes.dtype == np.float64
    assert np.isfinite(result.nodes).all()
    assert isinstance(result.confidence, float)
    assert 0.0 <= result.confidence <= 1.0
    assert isinstance(result.converged, bool)
    assert isinstance(result.iterations, int)
    assert result.iterations >= 0


def step_or_reject(tracker: Tracker, frame: Any, count: int = N) -> TrackResult | None:
    """Step; accept a ValueError that says something, and nothing else."""
    message = ""
    try:
        result = tracker.step(frame)
    except ValueError as exc:
        message = str(exc)
    if message:
        assert len(message) > 10, message
        return None
    check_result(result, count)
    return result


def upscaled(frame: U8, factor: int = 2) -> U8:
    """A frame drawn ``factor`` times as large (bilinear)."""
    h, w = frame.shape[:2]
    return np.asarray(cv2.resize(frame, (w * factor, h * factor), interpolation=cv2.INTER_LINEAR))


def larger(nodes: F64, factor: float = 2) -> F64:
    """``[x, y]`` points of a frame in pixels of the frame scaled by ``factor``."""
    result: F64 = (nodes + 0.5) * factor - 0.5
    return result


def run(tracker: Tracker, frames: list[U8]) -> list[TrackResult]:
    return [tracker.step(frame) for frame in frames]


def assert_same(a: TrackResult, b: TrackResult) -> None:
    np.testing.assert_array_equal(a.nodes, b.nodes)
    assert a.iterations == b.iterations
    assert a.converged == b.converged
    assert a.confidence == b.confidence


def resumes_alike(tracker: Tracker, state: dict[str, Any], frames: list[U8]) -> Tracker:
    """The tracker ``state`` restores, after checking that it tracks ``frames`` exactly as
    ``tracker`` (the one the state was taken from) does."""
    restored = Tracker.from_state(state)
    for a, b in zip(run(restored, frames), run(tracker, frames), strict=True):
        assert_same(a, b)
    return restored


def through_json(state: dict[str, Any]) -> dict[str, Any]:
    text = json.dumps(state, allow_nan=False)  # strict JSON: no NaN / Infinity
    loaded: dict[str, Any] = json.loads(text)
    return loaded
