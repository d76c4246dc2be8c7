"""engine.tracking.looks: one look per kind of frame, for videos that turn grey or colour."""

from __future__ import annotations

import copy
import json
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker

U8 = NDArray[np.uint8]
CLIP = make_sequence("clutter", seed=1, length=12, size=(120, 160))
START = mask_to_contour(CLIP.masks[0], 64)


def grey(frame: U8) -> U8:
    """The frame as a grey camera sends it, decoded to BGR: three equal channels."""
    return np.asarray(cv2.cvtColor(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), cv2.COLOR_GRAY2BGR))


def ious(frames: list[U8], tracker: Tracker | None = None) -> list[float]:
    tracker = tracker or Tracker(START)
    out = []
    for frame, mask in zip(frames, CLIP.masks, strict=False):
        nodes = tracker.step(frame).nodes
        out.append(mask_iou(contour_to_mask(nodes, mask.shape), mask))
    return out


def test_a_camera_turning_grey_is_followed_with_a_look_learnt_in_grey() -> None:
    """Colour, then grey from the fifth frame (a night mode): before the looks, the colour
    models read the grey frames' texture channels and J fell to 0.64 by the last frame."""
    frames = list(CLIP.frames[:4]) + [grey(f) for f in CLIP.frames[4:]]
    assert min(ious(frames)[1:]) > 0.8


def test_a_video_fading_in_from_grey_is_followed_in_colour() -> None:
    """The first frame grey, the rest colour: the colour look is learnt on the second
    (before, the grey frame's models read colours: J 0.63 by the last frame)."""
    frames = [grey(CLIP.frames[0]), *CLIP.frames[1:]]
    assert min(ious(frames)[2:]) > 0.9


def test_black_frames_leave_the_colour_look_as_it_was() -> None:
    """Two black frames (grey: three equal channels) in a colour video: the colour look
    waits aside and the frames after them track as if there had been none."""
    frames = list(CLIP.frames)
    frames[5] = frames[6] = np.zeros_like(frames[5])
    assert min(ious(frames)[7:]) > 0.9


def tinted(frame: U8) -> U8:
    """The frame as a monochrome camera with a warm cast sends it: each channel an affine
    function of the grey level (not three equal ones)."""
    level = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).astype(np.float32)
    toned = np.dstack([0.80 * level + 8, 0.92 * level + 6, level + 4])
    return np.asarray(np.clip(np.rint(toned), 0, 255), np.uint8)


def kinds(frames: list[U8]) -> list[bool]:
    """Whether each frame after the first was read as grey (the grey confidence model)."""
    tracker, out = Tracker(START), []
    for frame in frames:
        tracker.step(frame)
        if tracker.evidence is not None:
            out.append(tracker.evidence.grey)
    return out


def test_a_tinted_video_is_tracked_in_grey() -> None:
    """Its colours say nothing its grey level does not: its texture is read, as in grey
    (before, the colour models read the tint: the thirty DAVIS training sequences in
    sepia scored J 0.555 at 128 nodes, 0.651 read as grey).  This clip read as colour
    scores a mean IoU of 0.752 (its worst frame 0.660), read as grey 0.872 (0.806): the
    mean tells them apart, a single frame's dip less surely."""
    frames = [tinted(f) for f in CLIP.frames]
    assert all(kinds(frames))
    assert float(np.mean(ious(frames)[1:])) >= 0.85


def test_a_tint_keeps_a_colour_track_in_colour_and_a_grey_one_in_grey() -> None:
    """A colour scene may show one channel's levels for a while (the object hidden, a grey
    background), so a tinted frame changes no look; grey frames do."""
    after_colour = list(CLIP.frames[:4]) + [tinted(f) for f in CLIP.frames[4:]]
    assert not any(kinds(after_colour))
    after_grey = [grey(f) for f in CLIP.frames[:4]] + [tinted(f) for f in CLIP.frames[4:]]
    tracker = Tracker(START)
    for frame in after_grey:
        tracker.step(frame)
        assert not tracker.unconfirmed  # never a change of look
        assert tracker.evidence is None or tracker.evidence.grey


def test_the_results_of_a_switch_frame() -> None:
    """The first grey frame: the predicted contour, just below tracking; back in colour,
    the colour look tracks at once."""
    tracker = Tracker(START)
    for frame in CLIP.frames[:4]:
        tracker.step(frame)
    first_grey = tracker.step(grey(CLIP.frames[4]))
    assert first_grey.status == "uncertain"
    assert tracker.unconfirmed
    tracker.step(grey(CLIP.frames[5]))
    back = tracker.step(CLIP.frames[6])
    assert back.status == "tracking"


@pytest.mark.parametrize("compact", [False, True])
def test_a_state_with_a_look_aside_resumes(compact: bool) -> None:
    """Exactly (or, compact, closely) as the tracker that wrote it, after JSON."""
    frames = list(CLIP.frames[:4]) + [grey(f) for f in CLIP.frames[4:8]] + list(CLIP.frames[8:])
    tracker = Tracker(START)
    for frame in frames[:6]:
        tracker.step(frame)
    state = json.loads(json.dumps(tracker.to_state(compact=compact)))
    assert state["look"]["grey"] is True
    assert state["look"]["aside"]["grey"] is False
    resumed = Tracker.from_state(state)
    for frame in frames[6:]:
        ours, theirs = tracker.step(frame).nodes, resumed.step(frame).nodes
        if compact:
            shape = frame.shape[:2]
            assert mask_iou(contour_to_mask(ours, shape), contour_to_mask(theirs, shape)) > 0.9
        else:
            assert np.array_equal(ours, theirs)


def _with_look(look: dict[str, Any]) -> dict[str, Any]:
    tracker = Tracker(START)
    for frame in [*CLIP.frames[:3], grey(CLIP.frames[3])]:
        tracker.step(frame)
    state = copy.deepcopy(tracker.to_state())
    state["look"] = look(state["look"]) if callable(look) else look
    return state


@pytest.mark.parametrize(
    "look",
    [
        "grey",
        {"grey": "yes"},
        lambda look: {**look, "grey": False},  # the look aside is of the kind in use
        lambda look: {**look, "aside": {**look["aside"], "usual": [0.5, 0.5]}},
        lambda look: {**look, "aside": {**look["aside"], "stages": []}},
    ],
)
def test_a_malformed_look_is_refused(look: Any) -> None:
    with pytest.raises(ValueError, match=r"\S"):
        Tracker.from_state(_with_look(look))


def test_a_state_without_looks_resumes_and_learns_its_kind() -> None:
    """Written before the looks: the next frame sets the kind, as if it had been so."""
    tracker = Tracker(START)
    for frame in CLIP.frames[:3]:
        tracker.step(frame)
    state = tracker.to_state()
    del state["look"]
    resumed = Tracker.from_state(state)
    for frame in CLIP.frames[3:6]:
        assert np.array_equal(tracker.step(frame).nodes, resumed.step(frame).nodes)


def test_several_objects_follow_a_video_that_turns_grey_and_back() -> None:
    """Each object's tracker changes look; the frame's shared step of light between frames
    of two kinds is not taken for a change of light."""
    from engine.testing.crowd import make_crowd
    from engine.tracking import ObjectsTracker

    crowd = make_crowd(seed=0, length=16)
    frames = list(crowd.frames)
    frames[6:10] = [grey(f) for f in frames[6:10]]
    tracker = ObjectsTracker({k: mask_to_contour(m[0], 64) for k, m in enumerate(crowd.masks)})
    for i, frame in enumerate(frames):
        for k, result in enumerate(tracker.step(frame)):  # in the order they were added
            if i in (9, 15):  # the last grey frame, and back in colour
                truth = crowd.masks[k][i]
                mine = contour_to_mask(result.contours[0], truth.shape)
                assert mask_iou(mine, truth) > 0.9
