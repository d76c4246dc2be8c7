"""engine.tracking.regrid: a track's grid follows its object's size."""

from __future__ import annotations

from itertools import pairwise
from typing import Any

import numpy as np
import pytest

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.confidence import TRACKING_FROM
from engine.tracking.regrid import CHANGE, follow_size, grid_lines, rescaled_map
from engine.tracking.working import object_grid_side
from tests.engine.tracking.moving_disc import U8, assert_same, run, through_json

SIZE = (240, 320)
SIDE = 32
"""An ``object_side`` the generated objects (34-84 px) are larger than."""


def clip(seed: int) -> tuple[list[U8], list[Any]]:
    """A generated object that grows (seed 5: 43 to 84 px) or shrinks (seed 0: 81 to 42)."""
    sequence = make_sequence("scale_change", seed=seed, length=20, size=SIZE)
    return list(sequence.frames), [m > 0 for m in sequence.masks]


def lines(tracker: Tracker) -> int:
    previous = tracker.previous_frame
    assert previous is not None
    return int(previous.shape[0])


def follow(seed: int, **options: Any) -> tuple[list[int], list[float]]:
    """The grid's lines and the overlap on each frame of ``clip(seed)``."""
    frames, masks = clip(seed)
    tracker = Tracker(mask_to_contour(masks[0], 96), **options)
    grids, overlaps = [], []
    for frame, mask in zip(frames, masks, strict=True):
        nodes = tracker.step(frame).nodes
        grids.append(lines(tracker))
        overlaps.append(mask_iou(contour_to_mask(nodes, SIZE) > 0, mask))
    return grids, overlaps


def test_a_growing_object_moves_to_coarser_grids_and_is_followed() -> None:
    grids, overlaps = follow(5, object_side=SIDE)
    first = mask_to_contour(clip(5)[1][0], 96)
    assert grids[0] == object_grid_side(SIZE, first, 480, SIDE) < SIZE[0]  # as a track starts
    changes = [b for a, b in pairwise(grids) if a != b]
    assert len(changes) >= 2  # 43 -> 84 px: about twice the size, three quarter steps
    assert all(b < a for a, b in pairwise(grids) if a != b)
    assert grids[-1] < 0.7 * grids[0]
    assert min(overlaps[1:]) > 0.9
    kept, _ = follow(5, object_side=0)
    assert set(kept) == {SIZE[0]}  # without the object's grid: the frames as they are


def test_a_shrinking_object_moves_back_to_finer_grids() -> None:
    grids, overlaps = follow(0, object_side=SIDE)
    assert grids[-1] > 1.4 * grids[0]
    assert all(b > a for a, b in pairwise(grids) if a != b)
    assert min(overlaps[1:]) > 0.9


def test_the_grid_changes_only_by_a_quarter_or_more() -> None:
    grids, _ = follow(5, object_side=SIDE)
    for a, b in pairwise(grids):
        assert a == b or max(a, b) >= CHANGE * min(a, b) - 1  # -1: the sides are rounded


def test_a_track_resumed_across_a_change_of_grid_goes_on_bit_for_bit() -> None:
    frames, masks = clip(5)
    tracker = Tracker(mask_to_contour(masks[0], 96), object_side=SIDE)
    run(tracker, frames[:6])
    state = through_json(tracker.to_state())
    expected = run(tracker, frames[6:])
    resumed = Tracker.from_state(state)
    for a, b in zip(run(resumed, frames[6:]), expected, strict=True):
        assert_same(a, b)
    assert lines(resumed) == lines(tracker) < SIZE[0] * SIDE / 55  # it did change grid


def test_an_unconfident_track_keeps_its_grid() -> None:
    frames, masks = clip(5)
    tracker = Tracker(mask_to_contour(masks[0], 96), object_side=SIDE)
    run(tracker, frames[:2])
    tracker._nodes = tracker._nodes * 2.0  # a contour twice the object's size...
    tracker._reported = TRACKING_FROM - 0.01  # ...that is not confidently on it
    assert not follow_size(tracker)
    tracker._reported = TRACKING_FROM
    assert follow_size(tracker)


def test_a_stage_that_cannot_be_rescaled_keeps_the_first_grid() -> None:
    frames, masks = clip(5)
    nodes = mask_to_contour(masks[0], 96)

    class Fixed:  # the default cut without ``rescale``
        def __init__(self) -> None:
            self._cut = Tracker(nodes).segmentation

        def __getattr__(self, name: str) -> Any:
            if name == "rescale":
                raise AttributeError(name)
            return getattr(self._cut, name)

    tracker = Tracker(nodes, object_side=SIDE, segmentation=Fixed())
    first = None
    for frame in frames:
        tracker.step(frame)
        first = first or lines(tracker)
        assert lines(tracker) == first


def test_a_map_is_moved_onto_the_new_grid_to_within_half_a_pixel() -> None:
    values = np.zeros((40, 60), np.uint8)
    values[10:30, 20:40] = 255  # a square at (20..39, 10..29) of the region
    origin = (30, 16)

    def halve(points: Any) -> Any:  # a grid of half the lines: p -> (p + 1/2) / 2 - 1/2
        return (np.asarray(points, np.float64) + 0.5) / 2 - 0.5

    (x0, y0), moved = rescaled_map(origin, values, halve)
    assert (x0, y0) == (15, 8)
    assert moved.shape == (20, 30)
    ys, xs = np.nonzero(moved > 127)
    # the square's pixels 50..69 x 26..45 of the old grid: 25..34 x 13..22 of the new
    assert (xs.min() + x0, xs.max() + x0) == (25, 34)
    assert (ys.min() + y0, ys.max() + y0) == (13, 22)


@pytest.mark.parametrize(
    ("shape", "side", "expected"),
    [((480, 854), 0, 480), ((480, 854), 300, 300), ((480, 854), 600, 480)],
)
def test_grid_lines(shape: tuple[int, int], side: int, expected: int) -> None:
    assert grid_lines(shape, side) == expected


@pytest.mark.parametrize(("shape", "side"), [((0, 854), 0), ((480,), 0), ((480, 854), -1)])
def test_grid_lines_refuses_a_bad_shape_or_side(shape: Any, side: int) -> None:
    with pytest.raises(ValueError, match="must be"):
        grid_lines(shape, side)


@pytest.mark.parametrize(
    ("origin", "values"),
    [
        ((0, 0), np.zeros((0, 4), np.uint8)),
        ((0, 0), np.zeros((4, 4, 3), np.uint8)),
        ((0, 0), np.zeros((4, 4), np.float32)),
        ((-1, 0), np.zeros((4, 4), np.uint8)),
        ((0.5, 0), np.zeros((4, 4), np.uint8)),
    ],
)
def test_a_bad_map_is_refused(origin: Any, values: Any) -> None:
    with pytest.raises(ValueError, match="must be"):
        rescaled_map(origin, values, lambda p: p)
