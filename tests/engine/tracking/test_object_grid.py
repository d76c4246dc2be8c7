"""engine.tracking.working.object_grid_side: a large object is tracked on a grid of its size."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from engine.geometry import circle_nodes
from engine.tracking import Tracker
from engine.tracking.options import OBJECT_SIDE
from engine.tracking.working import MIN_GRID_SIDE, object_grid_side
from tests.engine.tracking.moving_disc import (
    F64,
    U8,
    H,
    R,
    W,
    assert_same,
    initial,
    larger,
    resumes_alike,
    run,
    through_json,
    upscaled,
)

UP = 4
"""The moving disc's frames drawn four times as large: 800 x 480, the disc's square root of
area about 142 px."""
SIZE = math.sqrt(math.pi) * R * UP
SIDE = 71
"""An ``object_side`` that brings those frames to about half their lines."""


def grid() -> int:
    """The lines of the grid the large disc is tracked on with :data:`SIDE`."""
    return object_grid_side((H * UP, W * UP), larger(initial(), UP), 480, SIDE)


def disc(size: float) -> F64:
    """A contour whose enclosed area's square root is ``size`` pixels (to 0.1 %)."""
    return circle_nodes((300.0, 200.0), size / math.sqrt(math.pi), 720)


@pytest.mark.parametrize(
    ("size", "working_side", "object_side", "expected"),
    [
        (100.0, 480, 160, 480),  # a smaller object: the working side alone
        (320.0, 480, 160, 240),  # twice as large: half the lines
        (320.0, 200, 160, 200),  # the working side is smaller still
        (320.0, 0, 160, 240),  # frames tracked as they are: the object's grid still
        (320.0, 480, 0, 480),  # 0: never
        (4000.0, 480, 160, MIN_GRID_SIDE),  # never fewer lines than a working side may have
    ],
)
def test_the_grid_shrinks_by_the_objects_size_over_object_side(
    size: float, working_side: int, object_side: int, expected: int
) -> None:
    side = object_grid_side((480, 854), disc(size), working_side, object_side)
    assert side == pytest.approx(expected, abs=1)


def test_a_degenerate_contour_keeps_the_working_side() -> None:
    line = np.array([[0.0, 0.0], [500.0, 500.0]])
    assert object_grid_side((480, 854), line, 480, 160) == 480
    flat = np.array([[0.0, 0.0], [500.0, 0.0], [900.0, 0.0]])
    assert object_grid_side((480, 854), flat, 480, 160) == 480


def test_the_default_is_160_pixels() -> None:
    assert Tracker(initial()).options.object_side == OBJECT_SIDE == 160


@pytest.mark.parametrize("side", [-1, 8, 15, 20_000, 1.5, "160", True, None])
def test_a_bad_object_side_is_refused(side: Any) -> None:
    with pytest.raises(ValueError, match="object_side must be 0 or an integer"):
        Tracker(initial(), object_side=side)


def test_a_large_object_is_tracked_on_the_grid_a_working_side_of_that_size_gives(
    frames: list[U8],
) -> None:
    big = [upscaled(f, UP) for f in frames[:8]]
    assert SIZE > SIDE
    tracker = Tracker(larger(initial(), UP), object_side=SIDE)
    by_size = run(tracker, big)
    previous = tracker.previous_frame
    assert previous is not None
    assert 235 <= grid() <= 245  # half the lines, give or take the polygon's area
    assert previous.shape[0] == grid()
    same_grid = run(Tracker(larger(initial(), UP), working_side=grid(), object_side=0), big)
    for a, b in zip(by_size, same_grid, strict=True):
        assert_same(a, b)  # in the frame's pixels, bit for bit


def test_an_object_below_object_side_is_tracked_as_without_it(frames: list[U8]) -> None:
    alone = run(Tracker(initial(), object_side=0), frames[:6])
    for a, b in zip(run(Tracker(initial()), frames[:6]), alone, strict=True):
        assert_same(a, b)


def test_a_reset_decides_the_grid_anew(frames: list[U8]) -> None:
    big = [upscaled(f, UP) for f in frames[:4]]
    tracker = Tracker(larger(initial(), UP), object_side=SIDE)
    run(tracker, big[:2])
    assert tracker.previous_frame is not None
    assert tracker.previous_frame.shape[0] == grid()
    tracker.reset(larger(initial(), UP) * 0.5 + 100.0)  # a quarter of the area: under the size
    run(tracker, big[2:])
    assert tracker.previous_frame is not None
    assert tracker.previous_frame.shape[0] == H * UP


def test_a_state_on_an_objects_grid_resumes_exactly(frames: list[U8]) -> None:
    big = [upscaled(f, UP) for f in frames[:10]]
    tracker = Tracker(larger(initial(), UP), object_side=SIDE)
    run(tracker, big[:5])
    state = through_json(tracker.to_state())
    assert state["grid_side"] == grid()
    expected = run(tracker, big[5:])
    for a, b in zip(run(Tracker.from_state(state), big[5:]), expected, strict=True):
        assert_same(a, b)


def test_a_state_from_before_the_objects_grid_resumes_on_the_working_grid(
    frames: list[U8],
) -> None:
    big = [upscaled(f, UP) for f in frames[:6]]
    tracker = Tracker(larger(initial(), UP), object_side=0)
    run(tracker, big[:3])
    state = through_json(tracker.to_state())
    del state["options"]["object_side"], state["grid_side"]
    assert resumes_alike(tracker, state, big[3:]).options.object_side == 0


@pytest.mark.parametrize("grid_side", [-1, 1.5, "240", True, 100])
def test_a_state_with_a_bad_grid_side_is_refused(grid_side: Any, frames: list[U8]) -> None:
    tracker = Tracker(larger(initial(), UP), object_side=SIDE)
    run(tracker, [upscaled(f, UP) for f in frames[:2]])
    state = through_json(tracker.to_state())
    state["grid_side"] = grid_side  # 100: not the grid the previous frame is on
    with pytest.raises(ValueError, match="malformed tracker state"):
        Tracker.from_state(state)


def test_a_frame_tracked_on_a_smaller_grid_is_made_grey_there_only(
    frames: list[U8], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``step`` converts to grey on the grid the frame is tracked on, not the frame as given,
    and tracks exactly as ``step_prepared`` handed the frame and its grey version."""
    import cv2

    from engine.tracking._frames import as_frame

    big = [upscaled(f, UP) for f in frames[:5]]
    prepared = Tracker(larger(initial(), UP), object_side=SIDE)
    expected = [prepared.step_prepared(*as_frame(frame)) for frame in big]
    sizes: list[tuple[int, ...]] = []
    convert = cv2.cvtColor

    def counted(image: U8, code: int) -> U8:
        sizes.append(image.shape[:2])
        return np.asarray(convert(image, code), np.uint8)

    monkeypatch.setattr(cv2, "cvtColor", counted)
    stepped = run(Tracker(larger(initial(), UP), object_side=SIDE), big)
    assert sizes  # the working grid's frames were made grey
    assert big[0].shape[:2] not in sizes
    for a, b in zip(stepped, expected, strict=True):
        assert_same(a, b)
    run(Tracker(initial()), frames[:3])  # tracked as given: made grey as given
    assert frames[0].shape[:2] in sizes
