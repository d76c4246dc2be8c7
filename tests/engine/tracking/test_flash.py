"""engine.tracking.flash: a washed-out (or blacked-out) frame passed over."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.confidence import UNCONFIRMED
from engine.tracking.flash import FLASH_FRAMES, FLASH_RATIO, flashed

U8 = NDArray[np.uint8]
CLIP = make_sequence("clutter", seed=1, length=14, size=(120, 160))
START = mask_to_contour(CLIP.masks[0], 64)
DIM = [np.asarray(f.astype(np.float32) * 0.6, np.uint8) for f in CLIP.frames]
"""The clip in a dim room (mean grey level 97 instead of 161), where a flash is used."""


def washed_out(frame: U8) -> U8:
    """A camera's flash: the frame at 0.3 of its contrast, lifted to near white."""
    return np.asarray(np.clip(frame.astype(np.float32) * 0.3 + 190, 0, 255), np.uint8)


def iou(nodes: NDArray[np.float64], t: int) -> float:
    mask = CLIP.masks[t]
    return mask_iou(contour_to_mask(nodes, mask.shape), mask)


def test_a_flash_is_a_frame_far_brighter_or_darker_than_the_last_tracked() -> None:
    grey = np.full((20, 30), 100, np.uint8)
    assert not flashed(grey, grey, 0)
    assert not flashed(grey + 20, grey, 0)  # a light turned up a little: followed
    brighter = np.full((20, 30), round(101 * FLASH_RATIO), np.uint8)
    assert flashed(brighter, grey, 0)
    assert flashed(grey, brighter, 0)  # and darker
    assert flashed(np.zeros_like(grey), grey, FLASH_FRAMES - 1)
    assert not flashed(brighter, grey, FLASH_FRAMES)  # a new light, after as many


def test_a_flash_is_passed_over_and_the_track_goes_on_from_before_it() -> None:
    frames = list(DIM)
    frames[6] = washed_out(frames[6])
    tracker = Tracker(START)
    results = [tracker.step(frame) for frame in frames]
    assert np.array_equal(results[6].nodes, results[5].nodes)  # the last contour
    assert results[6].status == "uncertain"
    assert tracker.evidence is not None  # the frames after it are tracked
    assert min(iou(r.nodes, t) for t, r in enumerate(results) if t != 6) > 0.9
    assert [r.status for r in results[7:]] == ["tracking"] * (len(frames) - 7)


def test_a_new_light_is_followed_after_the_frames_a_flash_may_last() -> None:
    frames = DIM[:4] + [washed_out(f) for f in DIM[4:]]
    tracker = Tracker(START)
    results = [tracker.step(frame) for frame in frames]
    passed = [t for t, r in enumerate(results) if np.array_equal(r.nodes, results[t - 1].nodes)]
    assert passed == list(range(4, 4 + FLASH_FRAMES))
    assert tracker.evidence is not None  # tracked from the third washed-out frame on


def test_a_state_written_on_a_flash_resumes_exactly() -> None:
    frames = list(DIM)
    frames[5] = frames[6] = washed_out(frames[5])
    tracker = Tracker(START)
    for frame in frames[:6]:
        tracker.step(frame)
    state = json.loads(json.dumps(tracker.to_state()))
    assert state["passed"] == 1
    resumed = Tracker.from_state(state)
    for frame in frames[6:]:
        assert np.array_equal(tracker.step(frame).nodes, resumed.step(frame).nodes)
    del state["passed"]  # written before the flashes: none passed over
    assert Tracker.from_state(state).to_state()["passed"] == 0


def test_a_flash_reports_no_more_confidence_than_the_frame_before() -> None:
    """A lost object stays lost through the flash: the last contour is reported with the
    lower of its confidence and just below tracking."""
    tracker = Tracker(START)
    last = [tracker.step(frame) for frame in DIM[:4]][-1]
    state = json.loads(json.dumps(tracker.to_state()))
    assert state["reported"] == last.confidence
    assert last.status == "tracking"
    state["reported"] = 0.1  # as if the last frame had been lost
    lost = Tracker.from_state(state).step(washed_out(DIM[4]))
    assert (lost.confidence, lost.status) == (0.1, "lost")
    passed = tracker.step(washed_out(DIM[4]))
    assert (passed.confidence, passed.status) == (UNCONFIRMED, "uncertain")


@pytest.mark.parametrize(
    ("key", "value"),
    [
        *(("reported", v) for v in (-0.1, 1.5, "0.5", None)),
        *(("passed", v) for v in (-1, FLASH_FRAMES + 1, 1.5, "1", True)),
    ],
)
def test_a_malformed_flash_record_is_refused(key: str, value: object) -> None:
    """The confidence last reported, and the count of frames passed over as a flash."""
    tracker = Tracker(START)
    for frame in CLIP.frames[:3]:
        tracker.step(frame)
    state = tracker.to_state()
    state[key] = value
    with pytest.raises(ValueError, match="malformed tracker state"):
        Tracker.from_state(state)
