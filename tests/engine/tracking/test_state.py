"""engine.Tracker state: JSON snapshots, exact resume, versions and malformed input."""

from __future__ import annotations

import base64
import copy
import dataclasses
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from engine import TrackerOptions, TrackResult
from engine.geometry import circle_nodes, contour_to_mask, mask_iou
from engine.tracking._state_codec import pack_counts as _pack_counts
from engine.tracking._state_codec import pack_histogram as _pack
from engine.tracking._tracker_state import STATE_VERSION
from engine.tracking.appearance import LEGACY_COLOUR_BITS, ColourHistogram
from engine.tracking.tracker import Tracker
from tests.engine.tracking.moving_disc import (
    H,
    R,
    W,
    assert_same,
    centre,
    check_result,
    initial,
    run,
    through_json,
)

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]
State = dict[str, Any]
VERSION_1 = Path(__file__).parent / "data" / "tracker_state_v1.json"
"""Written by the tracker of version 1 after frames 0-4 of the moving disc."""


@pytest.fixture(scope="module")
def tracked_state(frames: list[U8]) -> tuple[State, list[TrackResult], F64]:
    """State after 5 frames, the uninterrupted results of frames 5-9, and the nodes at 5."""
    tracker = Tracker(initial())
    run(tracker, frames[:5])
    state = through_json(tracker.to_state())
    nodes = tracker.nodes
    return state, run(tracker, frames[5:10]), nodes


def test_state_is_json_and_names_every_option(
    tracked_state: tuple[State, list[TrackResult], F64],
) -> None:
    state, _, _ = tracked_state
    assert through_json(state) == state
    assert set(state["options"]) == {f.name for f in dataclasses.fields(TrackerOptions)}
    assert state["frame_index"] == 4
    assert state["version"] == STATE_VERSION
    assert set(state["stages"]) == {"motion", "appearance", "cues", "segmentation"}
    # the corners being tracked on, for an exact resume
    features = state["stages"]["motion"]["features"]
    assert len(features) >= 3
    assert all(len(point) == 2 for point in features)


def test_state_round_trip_restores_the_contour_exactly(
    tracked_state: tuple[State, list[TrackResult], F64],
) -> None:
    state, _, nodes = tracked_state
    restored = Tracker.from_state(state)
    assert restored.frame_index == 4
    np.testing.assert_array_equal(restored.nodes, nodes)


def test_state_round_trip_continues_identically(
    frames: list[U8], tracked_state: tuple[State, list[TrackResult], F64]
) -> None:
    state, expected, _ = tracked_state
    restored = Tracker.from_state(state)
    for frame, want in zip(frames[5:10], expected, strict=True):
        assert_same(restored.step(frame), want)
    assert restored.frame_index == 9


def test_a_contour_shrunk_below_a_pixel_resumes(frames: list[U8]) -> None:
    """A new contour must enclose a square pixel; a tracked one that shrank below it (on tiny
    random frames, found by the property test) still resumes, exactly."""
    tracker = Tracker(initial())
    run(tracker, frames[:2])
    state = through_json(tracker.to_state())
    tiny = circle_nodes((40.0, 30.0), 0.2, len(state["nodes"]))
    state["nodes"] = tiny.tolist()
    restored = Tracker.from_state(state)
    np.testing.assert_array_equal(restored.nodes, tiny)
    check_result(restored.step(frames[2]), len(tiny))


def test_state_before_any_frame(frames: list[U8]) -> None:
    tracker = Tracker(initial(), iterations=3)
    restored = Tracker.from_state(through_json(tracker.to_state()))
    assert restored.options.iterations == 3
    assert restored.frame_index == -1
    assert_same(restored.step(frames[0]), tracker.step(frames[0]))


def test_far_background_is_kept_through_a_state_and_read_as_off_when_missing(
    frames: list[U8],
) -> None:
    tracker = Tracker(initial(), far_background=0.2)
    run(tracker, frames[:3])
    state = through_json(tracker.to_state())
    restored = Tracker.from_state(state)
    assert restored.options.far_background == 0.2
    assert getattr(restored.appearance, "far_background", None) == 0.2
    for frame in frames[3:6]:
        assert_same(restored.step(frame), tracker.step(frame))
    del state["options"]["far_background"]  # written before the option
    assert Tracker.from_state(state).options.far_background == 0.0


@pytest.mark.parametrize(
    "option",
    [
        "rigid_behind",
        "revealed_background",
        "bridge_strips",
        "carve_gaps",
        "full_resolution_edges",
        "align_prediction",
        "turn_outline",
    ],
)
def test_an_option_added_later_is_kept_through_a_state_and_read_as_off_when_missing(
    option: str, frames: list[U8]
) -> None:
    on: dict[str, Any] = {option: True}
    tracker = Tracker(initial(), **on)
    run(tracker, frames[:3])
    state = through_json(tracker.to_state())
    assert getattr(Tracker.from_state(state).options, option) is True
    del state["options"][option]  # written before the option
    assert getattr(Tracker.from_state(state).options, option) is False


def test_colour_levels_are_kept_through_a_state_and_read_as_16_when_missing(
    frames: list[U8],
) -> None:
    tracker = Tracker(initial())
    run(tracker, frames[:3])
    state = through_json(tracker.to_state())
    restored = Tracker.from_state(state)
    assert restored.options.colour_bits == 5
    for frame in frames[3:6]:
        assert_same(restored.step(frame), tracker.step(frame))
    state["options"]["colour_bits"] = LEGACY_COLOUR_BITS  # histograms of another size
    with pytest.raises(ValueError, match="colour_bits=4"):
        Tracker.from_state(state)
    old = Tracker(initial(), colour_bits=LEGACY_COLOUR_BITS)
    run(old, frames[:3])
    state = through_json(old.to_state())
    del state["options"]["colour_bits"]  # written before the option: 16 levels
    restored = Tracker.from_state(state)
    assert restored.options.colour_bits == LEGACY_COLOUR_BITS
    for frame in frames[3:6]:
        assert_same(restored.step(frame), old.step(frame))


def test_state_without_frame_reinitialises_on_the_next_frame(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    run(tracker, frames[:5])
    state = through_json(tracker.to_state(include_frame=False))
    assert len(json.dumps(state)) < 4000  # no image, no histograms
    restored = Tracker.from_state(state)
    np.testing.assert_allclose(restored.nodes, tracker.nodes, atol=0.05)
    before = restored.nodes
    result = restored.step(frames[5])
    check_result(result)
    np.testing.assert_array_equal(result.nodes, before)
    assert result.iterations == 0
    assert result.converged is True
    assert result.confidence == 1.0
    assert restored.frame_index == 5
    # and tracking goes on from there
    for i in range(6, 10):
        result = restored.step(frames[i])
    truth = contour_to_mask(circle_nodes(centre(9), R, 720), (H, W))
    assert mask_iou(contour_to_mask(result.nodes, (H, W)), truth) >= 0.9


def pack(values: NDArray[Any] | list[float]) -> str:
    """A histogram encoded the way states store them (the engine's own encoder)."""
    return _pack(np.asarray(values, dtype=np.float64))


def setter(*path: str | int, value: Any) -> Callable[[State], None]:
    def apply(state: State) -> None:
        target: Any = state
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value

    return apply


def histogram(which: str, value: str) -> Callable[[State], None]:
    return setter("stages", "appearance", which, value=value)


def deleter(key: str) -> Callable[[State], None]:
    def apply(state: State) -> None:
        del state[key]

    return apply


MALFORMED: dict[str, Callable[[State], None]] = {
    "version 4": setter("version", value=4),
    "version 0": setter("version", value=0),
    "version as text": setter("version", value="2"),
    "no version": deleter("version"),
    "no nodes": deleter("nodes"),
    "no options": deleter("options"),
    "no frame_index": deleter("frame_index"),
    "NaN node": setter("nodes", 0, 0, value=math.nan),
    "nodes not pairs": setter("nodes", value=[[1.0, 2.0, 3.0]] * 5),
    "nodes as text": setter("nodes", value="circle"),
    "nodes coincide": setter("nodes", value=[[5.0, 5.0]] * 8),
    "options not a mapping": setter("options", value=[1, 2]),
    "options null": setter("options", value=None),
    "unknown option": setter("options", "warp_speed", value=9),
    "bad option value": setter("options", "iterations", value=0),
    "frame_index text": setter("frame_index", value="four"),
    "frame_index null": setter("frame_index", value=None),
    "previous: bad base64": setter("previous", value="!!! not base64 !!!"),
    "previous: not an image": setter("previous", value=base64.b64encode(b"hello").decode()),
    "previous: a number": setter("previous", value=12),
    "histogram: bad base64": histogram("object", "@@@@"),
    "histogram: NaN": histogram("object", pack(np.full(4096, np.nan))),
    "histogram: infinite": setter(
        "stages", "appearance", "background", value=pack(np.full(4096, np.inf))
    ),
    "histogram: negative": setter(
        "stages", "appearance", "object", value=pack(np.full(4096, -1.0))
    ),
    "histogram: not encoded": setter(
        "stages", "appearance", "object", value=base64.b64encode(b"abc").decode()
    ),
    "appearance: no object": setter(
        "stages",
        "appearance",
        value={"kind": "colour-histogram", "background": pack(np.ones(4096) / 4096)},
    ),
    "appearance: a list": setter("stages", "appearance", value=[1, 2]),
    "appearance: unknown dtype": setter("stages", "appearance", "dtype", value="float32"),
    "appearance: dtype a number": setter("stages", "appearance", "dtype", value=16),
    "histogram: float16 read as float64": setter(
        "stages", "appearance", "object", value=_pack(np.ones(4096) / 4096, "float16")
    ),
    "appearance: another kind": setter("stages", "appearance", "kind", value="neural"),
    "stages: a list": setter("stages", value=[1, 2]),
    "stages: no motion": lambda state: state["stages"].pop("motion"),
    "motion: another kind": setter("stages", "motion", "kind", value="kalman"),
    "cues: no kind": lambda state: state["stages"]["cues"].pop("kind"),
    "cues: bad memory": setter("stages", "cues", "memory", value={"origin": [0, 0], "png": "@"}),
    "features: NaN": setter("stages", "motion", "features", value=[[math.nan, 1.0]] * 4),
    "features: not pairs": setter("stages", "motion", "features", value=[1.0, 2.0, 3.0]),
    "features: text": setter("stages", "motion", "features", value="corners"),
    "segmentation: another kind": setter("stages", "segmentation", "kind", value="grabcut"),
    "segmentation: windows a list": setter("stages", "segmentation", "windows", value=[1]),
    "segmentation: bad counts": setter(
        "stages", "segmentation", "windows", "object", value=base64.b64encode(b"x").decode()
    ),
    "segmentation: negative counts": setter(
        "stages",
        "segmentation",
        "windows",
        "object",
        value=_pack_counts(-np.ones((32, 512), np.float32)),
    ),
    "segmentation: no window size": lambda state: state["stages"]["segmentation"]["windows"].pop(
        "half"
    ),
    "search: a string": setter("search", value="lost"),
    "frame index: infinite": setter("frame_index", value=math.inf),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_from_state_rejects_malformed_state(
    name: str, tracked_state: tuple[State, list[TrackResult], F64]
) -> None:
    state = copy.deepcopy(tracked_state[0])
    MALFORMED[name](state)
    with pytest.raises(ValueError, match=r"\S"):
        Tracker.from_state(state)


@pytest.mark.parametrize("state", [None, [], "state", 1], ids=repr)
def test_from_state_rejects_non_dicts(state: Any) -> None:
    with pytest.raises(ValueError, match="version"):
        Tracker.from_state(state)


INCONSISTENT_HISTOGRAMS: dict[str, tuple[str, str]] = {
    "object shorter than background": (pack(np.ones(10) / 10), pack(np.ones(4096) / 4096)),
    "both empty": (pack([]), pack([])),
    "both of a size no frame has": (pack(np.ones(10) / 10), pack(np.ones(10) / 10)),
}


@pytest.mark.parametrize("name", list(INCONSISTENT_HISTOGRAMS))
def test_from_state_rejects_inconsistent_histograms(
    name: str, frames: list[U8], tracked_state: tuple[State, list[TrackResult], F64]
) -> None:
    """A model that cannot belong to any frame is malformed: reject it, do not fail later."""
    state = copy.deepcopy(tracked_state[0])
    appearance = state["stages"]["appearance"]
    appearance["object"], appearance["background"] = INCONSISTENT_HISTOGRAMS[name]
    with pytest.raises(ValueError, match="malformed"):
        Tracker.from_state(state)


def test_a_version_1_state_resumes_exactly(frames: list[U8]) -> None:
    """States written before the stages (version 1) continue as if uninterrupted."""
    old: State = json.loads(VERSION_1.read_text())
    assert old["version"] == 1
    # version 1 had no segmentation stage, no motion contrast, no figure-ground split, no
    # shape memory, no lighting, no far background and no rigid prediction behind occluders
    tracker = Tracker(
        initial(),
        cut_band=0,
        motion_contrast=False,
        figure_ground=False,
        shape_memory=False,
        lighting=False,
        far_background=0.0,
        rigid_behind=False,
        revealed_background=False,
        bridge_strips=False,
        carve_gaps=False,
        full_resolution_edges=False,
        align_prediction=False,
    )
    # and its colour histograms had 16 levels a channel: the state resumes at them
    opts = tracker.options
    tracker.appearance = ColourHistogram(opts.band, opts.learning_rate, 0.0, LEGACY_COLOUR_BITS)
    run(tracker, frames[:5])
    expected = run(tracker, frames[5:10])
    restored = Tracker.from_state(old)
    assert getattr(restored.appearance, "colour_bits", None) == LEGACY_COLOUR_BITS
    assert restored.options.cut_band == 0
    assert restored.options.motion_contrast is False
    assert restored.frame_index == 4
    for frame, want in zip(frames[5:10], expected, strict=True):
        got = restored.step(frame)
        # the contour exactly; the confidence reads the ring against how it usually looks,
        # which the old state does not hold: learnt afresh from the frames after it
        np.testing.assert_array_equal(got.nodes, want.nodes)
        assert (got.iterations, got.converged) == (want.iterations, want.converged)
        assert got.confidence == pytest.approx(want.confidence, abs=0.01)
    upgraded = restored.to_state()
    assert upgraded["version"] == STATE_VERSION
    assert upgraded["search"]["usual"][2] == 5


def test_the_usual_look_goes_through_a_state(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    run(tracker, frames[:4])
    state = through_json(tracker.to_state())
    inside, outside, counted = state["search"]["usual"]
    assert counted == 3  # the frames tracked after the first
    assert 0.0 <= outside < inside <= 1.0
    restored = Tracker.from_state(state)
    for frame in frames[4:8]:
        assert_same(restored.step(frame), tracker.step(frame))
    del state["search"]["usual"]  # written before it: learnt afresh
    assert Tracker.from_state(state).to_state()["search"]["usual"] == [0.0, 0.0, 0]


def test_a_version_2_state_resumes_exactly(frames: list[U8]) -> None:
    """States written before the segmentation stage continue as the tracker that wrote them."""
    tracker = Tracker(initial(), cut_band=0, motion_contrast=False, figure_ground=False)
    run(tracker, frames[:5])
    old = through_json(tracker.to_state())
    old["version"] = 2
    del old["stages"]["segmentation"]
    del old["options"]["cut_band"]
    del old["options"]["motion_contrast"]
    del old["options"]["figure_ground"]
    expected = run(tracker, frames[5:10])
    restored = Tracker.from_state(old)
    assert restored.options.cut_band == 0
    for frame, want in zip(frames[5:10], expected, strict=True):
        assert_same(restored.step(frame), want)


@pytest.mark.parametrize("key", ["model", "probability", "features", "previous"])
def test_a_version_1_state_with_a_part_missing_still_loads(key: str, frames: list[U8]) -> None:
    old: State = json.loads(VERSION_1.read_text())
    old[key] = None
    restored = Tracker.from_state(old)
    check_result(restored.step(frames[5]))


def test_a_version_1_state_is_refused_by_other_stages() -> None:
    """Version 1 was only ever written by the default stages."""

    class Still:
        def reset(self) -> None: ...

        def predict(self, *args: Any, **kwargs: Any) -> Any: ...

        def to_state(self) -> dict[str, Any]:
            return {"kind": "still"}

        def from_state(self, state: Any) -> Still:
            if state.get("kind") != "still":
                raise ValueError("not a still state")
            return self

    with pytest.raises(ValueError, match="malformed"):
        Tracker.from_state(json.loads(VERSION_1.read_text()), motion=Still())


def test_a_frame_is_kept_as_text_exactly_grey_or_colour() -> None:
    from engine.tracking import pack_image, unpack_image

    rng = np.random.default_rng(4)
    colour = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    grey = colour[..., 1].copy()
    np.testing.assert_array_equal(unpack_image(pack_image(colour), colour=True), colour)
    np.testing.assert_array_equal(unpack_image(pack_image(grey), colour=True), grey)
    np.testing.assert_array_equal(unpack_image(pack_image(grey)), grey)
    assert unpack_image(pack_image(colour)).shape == (17, 23)  # read grey unless asked
    ramp = np.add.outer(np.arange(48), np.arange(64)).astype(np.uint8)  # smooth, as frames
    smooth = np.stack([ramp, ramp[::-1], 255 - ramp], axis=2)
    lossy = unpack_image(pack_image(smooth, quality=90), colour=True)
    assert lossy.shape == smooth.shape
    assert np.abs(lossy.astype(int) - smooth).mean() < 3  # JPEG: close, not exact
    for bad in ("", base64.b64encode(b"not a png").decode()):
        with pytest.raises(ValueError, match="decode"):
            unpack_image(bad, colour=True)


def test_a_track_lost_for_long_resumes_and_searches(
    frames: list[U8], tracked_state: tuple[State, list[TrackResult], F64]
) -> None:
    """A million frames without the object (as a state may say): the widest search, not an
    OverflowError on the next frame."""
    state = copy.deepcopy(tracked_state[0])
    state["search"]["misses"] = 10**6
    result = Tracker.from_state(state).step(frames[-1])
    assert np.isfinite(result.nodes).all()
