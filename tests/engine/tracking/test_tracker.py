"""engine.Tracker: tracking quality, first-frame behaviour, state round trips, robustness."""

from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from numpy.typing import NDArray

from engine import TrackerOptions
from engine.geometry import circle_nodes, contour_to_mask, mask_iou, polygon_area, resample
from engine.tracking.confidence import TRACKING_FROM
from engine.tracking.tracker import Tracker
from tests.engine.scenes import DiscScene, centroid
from tests.engine.tracking.moving_disc import (
    H,
    N,
    R,
    T,
    W,
    assert_same,
    centre,
    check_result,
    initial,
    run,
    step_or_reject,
    through_json,
)

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

# --- tracking quality ------------------------------------------------------------------------


def test_follows_a_translating_textured_disc(scene: DiscScene, frames: list[U8]) -> None:
    tracker = Tracker(initial())
    confidences = []
    for i, frame in enumerate(frames):
        result = tracker.step(frame)
        check_result(result)
        truth = scene.mask(centre(i))
        found = contour_to_mask(result.nodes, scene.shape)
        iou = mask_iou(found, truth)
        error = float(np.hypot(*(centroid(found) - centroid(truth))))
        assert iou >= 0.9, f"frame {i}: IoU {iou:.3f}"
        assert error < 2.0, f"frame {i}: centroid off by {error:.2f} px"
        confidences.append(result.confidence)
    assert tracker.frame_index == T - 1
    assert float(np.median(confidences)) >= 0.5  # tracking well is not "lost"


def test_grey_frames_are_tracked_like_single_channel_frames(frames: list[U8]) -> None:
    grey = [np.asarray(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), np.uint8) for f in frames[:6]]
    plain = run(Tracker(initial()), grey)
    single = run(Tracker(initial()), [g[..., None] for g in grey])
    for a, b in zip(plain, single, strict=True):
        check_result(a)
        assert_same(a, b)


def test_bgra_frames_are_tracked_like_bgr(frames: list[U8]) -> None:
    bgr = run(Tracker(initial()), frames[:5])
    bgra = run(
        Tracker(initial()),
        [np.asarray(cv2.cvtColor(f, cv2.COLOR_BGR2BGRA), np.uint8) for f in frames[:5]],
    )
    for a, b in zip(bgr, bgra, strict=True):
        assert_same(a, b)


def test_duplicate_initial_nodes_are_spread_out(scene: DiscScene, frames: list[U8]) -> None:
    doubled = np.repeat(initial()[::2], 2, axis=0)  # every node twice: N nodes, N / 2 places
    tracker = Tracker(doubled)
    nodes = tracker.nodes
    assert nodes.shape == (N, 2)
    gaps = np.hypot(*np.diff(np.vstack([nodes, nodes[:1]]), axis=0).T)
    assert gaps.min() > 0.9 * gaps.mean()
    for i, frame in enumerate(frames[:5]):
        result = tracker.step(frame)
        check_result(result)
        found = contour_to_mask(result.nodes, scene.shape)
        assert mask_iou(found, scene.mask(centre(i))) >= 0.85


# --- construction, first frame, reset --------------------------------------------------------


def test_first_step_returns_the_resampled_initial_contour(frames: list[U8]) -> None:
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, 2 * np.pi, N))  # unevenly spaced initial nodes
    nodes = np.stack([centre(0)[0] + R * np.cos(t), centre(0)[1] + R * np.sin(t)], axis=1)
    tracker = Tracker(nodes)
    assert tracker.frame_index == -1
    expected = resample(nodes, N)
    np.testing.assert_allclose(tracker.nodes, expected, atol=1e-9)
    result = tracker.step(frames[0])
    check_result(result)
    np.testing.assert_allclose(result.nodes, expected, atol=1e-9)
    assert result.converged is True
    assert result.iterations == 0
    assert result.confidence == 1.0
    assert tracker.frame_index == 0


def test_reset_places_a_new_contour_taken_as_lying_on_the_next_frame(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    run(tracker, frames[:3])
    new = circle_nodes((100.0, 60.0), 15.0, 40)
    tracker.reset(new)
    np.testing.assert_allclose(tracker.nodes, resample(new, 40), atol=1e-9)
    result = tracker.step(frames[10])
    check_result(result, 40)
    np.testing.assert_allclose(result.nodes, resample(new, 40), atol=1e-9)
    assert result.iterations == 0
    assert result.converged is True
    assert tracker.frame_index == 3


def test_nodes_and_results_are_copies(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    before = tracker.nodes
    tracker.nodes[0] = -1000.0
    result = tracker.step(frames[0])
    result.nodes[:] = 0.0
    np.testing.assert_array_equal(tracker.nodes, before)


def test_options_defaults_and_keywords() -> None:
    tracker = Tracker(initial())
    assert tracker.options == TrackerOptions()
    tuned = Tracker(initial(), stiffness=3.5, iterations=4, search_radius=6)
    assert tuned.options.stiffness == 3.5
    assert tuned.options.iterations == 4
    assert tuned.options.search_radius == 6
    with pytest.raises(dataclasses.FrozenInstanceError):
        tuned.options.stiffness = 1.0  # type: ignore[misc]


def test_rejected_frames_do_not_advance_the_tracker(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    tracker.step(frames[0])
    with pytest.raises(ValueError, match="uint8"):
        tracker.step(frames[1].astype(np.float32))
    assert tracker.frame_index == 0
    a = tracker.step(frames[1])
    b = Tracker(initial())
    b.step(frames[0])
    assert_same(a, b.step(frames[1]))


# --- robustness: frames ----------------------------------------------------------------------


def test_random_bytes_as_frames() -> None:
    tracker = Tracker(initial())
    for _ in range(4):
        noise = np.frombuffer(os.urandom(H * W * 3), np.uint8).reshape(H, W, 3)
        step_or_reject(tracker, noise)


def test_random_bytes_as_a_flat_buffer() -> None:
    tracker = Tracker(initial())
    with pytest.raises(ValueError, match="shape"):
        tracker.step(np.frombuffer(os.urandom(H * W * 3), np.uint8))


@pytest.mark.parametrize("shape", [(0, 0), (0, 10, 3), (10, 0), (0,)], ids=str)
def test_empty_frames_are_rejected(shape: tuple[int, ...]) -> None:
    with pytest.raises(ValueError, match="empty"):
        Tracker(initial()).step(np.zeros(shape, np.uint8))


@pytest.mark.parametrize("shape", [(1, 1), (2, 2), (2, 2, 3), (1, 1, 1), (1, 1, 4)], ids=str)
def test_tiny_frames(shape: tuple[int, ...], frames: list[U8]) -> None:
    tracker = Tracker(initial())
    for _ in range(3):
        result = step_or_reject(tracker, np.full(shape, 77, np.uint8))
        if result is not None:
            assert result.confidence == 0.0  # nothing to see in a 2 x 2 frame
    step_or_reject(tracker, frames[0])


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint16, np.int8, np.bool_])
def test_frames_that_are_not_uint8_are_rejected(dtype: type, frames: list[U8]) -> None:
    with pytest.raises(ValueError, match="uint8"):
        Tracker(initial()).step(frames[0].astype(dtype))


@pytest.mark.parametrize(
    "frame",
    [
        [[0, 1], [2, 3]],
        None,
        "frame.png",
        np.zeros((20, 20, 2), np.uint8),
        np.zeros((20, 20, 5), np.uint8),
        np.zeros((20, 20, 3, 1), np.uint8),
    ],
    ids=["list", "None", "str", "2 channels", "5 channels", "4-D"],
)
def test_frames_of_the_wrong_kind_are_rejected(frame: Any) -> None:
    with pytest.raises(ValueError, match="frame"):
        Tracker(initial()).step(frame)


def test_frame_size_changing_mid_stream(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    big = [np.asarray(cv2.resize(f, (2 * W, 2 * H)), np.uint8) for f in frames[2:4]]
    crop = [f[:, : W // 2].copy() for f in frames[4:6]]
    grey = [np.asarray(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), np.uint8) for f in frames[6:8]]
    for frame in [*frames[:2], *big, *crop, frames[6], *grey, frames[8], big[0]]:
        step_or_reject(tracker, frame)


def test_black_frames_lower_the_confidence(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    run(tracker, frames[:3])
    before = tracker.nodes
    black = np.zeros_like(frames[0])
    results = [tracker.step(black) for _ in range(6)]
    for result in results:
        check_result(result)
    # nothing tells the contour from its surroundings: never reported tracking
    assert all(r.confidence < TRACKING_FROM for r in results[2:]), [r.confidence for r in results]
    assert all(r.status != "tracking" for r in results[2:])
    # with nothing to see the contour neither wanders off nor collapses
    shift = np.hypot(*(results[-1].nodes.mean(axis=0) - before.mean(axis=0)))
    assert shift < 5.0
    assert abs(polygon_area(results[-1].nodes)) > 0.5 * abs(polygon_area(before))


def test_contour_partly_outside_the_frame(scene: DiscScene) -> None:
    path = [(2.0 + 4 * i, 60.0) for i in range(6)]  # starts half outside, moves in
    tracker = Tracker(circle_nodes(path[0], R, N))
    for i, c in enumerate(path):
        result = step_or_reject(tracker, scene.frame(c))
        assert result is not None
        if i == 0:
            assert result.confidence > 0.0  # half of it is in view
    assert result is not None
    found = contour_to_mask(result.nodes, scene.shape)
    assert mask_iou(found, scene.mask(path[-1])) >= 0.8


# (W / 2, -40) -- just above the frame -- is in test_short_wide_regions_do_not_crash_the_process
@pytest.mark.parametrize("where", [(-100.0, -100.0), (W + 50.0, H / 2), (W / 2, H + 80)], ids=str)
def test_contour_wholly_outside_the_frame(where: tuple[float, float], frames: list[U8]) -> None:
    tracker = Tracker(circle_nodes(where, 15.0, 32))
    for frame in frames[:4]:
        result = step_or_reject(tracker, frame, 32)
        assert result is not None
        assert result.confidence == 0.0


def test_frames_out_of_view_count_as_missed(frames: list[U8]) -> None:
    """Found by a review: only frames that searched counted, so an object back from beyond
    the frame's edge was never back after an absence (the cues not started anew)."""
    tracker = Tracker(circle_nodes((W + 50.0, H / 2), 15.0, 32))
    for frame in frames[:5]:
        assert tracker.step(frame).confidence == 0.0
    assert tracker._memory.misses == 4  # every frame after the first


@pytest.mark.parametrize(
    "nodes",
    [
        circle_nodes((W / 2, H / 2), 1e6, 64),
        np.array([[-1e8, -1e8], [1e8, -1e8], [1e8, 1e8], [-1e8, 1e8]]),
        circle_nodes((W / 2, H / 2), 2.0 * (W + H), 64),
    ],
    ids=["radius 1e6", "box 1e8", "just around the frame"],
)
def test_a_contour_around_the_whole_frame_is_tracked_as_unseen(
    nodes: F64, frames: list[U8]
) -> None:
    """Its windows and maps stay within the frame's size (a radius of 10^6 once asked for
    more memory than there is) and, with none of its boundary in view, it is never
    reported on anything."""
    tracker = Tracker(nodes)
    for frame in frames[:3]:
        result = tracker.step(frame)
        check_result(result, len(nodes))
        assert result.confidence == 0.0
        assert result.status == "lost"


CRASH_PROBE = """
import sys
import numpy as np
from engine import Tracker
from engine.geometry import circle_nodes

shape, centre, radius = eval(sys.argv[1])
rng = np.random.default_rng(0)
tracker = Tracker(circle_nodes(centre, radius, 32))
for _ in range(3):
    try:
        result = tracker.step(rng.integers(0, 256, shape, dtype=np.uint8))
    except ValueError:
        continue
    assert np.isfinite(result.nodes).all()
    assert 0.0 <= result.confidence <= 1.0
print("survived")
"""


@pytest.mark.parametrize(
    "case",
    [
        "((20, 160, 3), (80.0, 10.0), 6.0)",  # a short, wide frame
        "((24, 128), (60.0, 12.0), 8.0)",
        "((120, 200, 3), (100.0, -40.0), 15.0)",  # contour just above a normal frame
    ],
)
def test_short_wide_regions_do_not_crash_the_process(case: str) -> None:
    """Run in a child process: a crash in native code must fail this test, not end the run."""
    child = subprocess.run(
        [sys.executable, "-c", CRASH_PROBE, case],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert child.returncode == 0, f"exit code {child.returncode}\n{child.stderr[-2000:]}"
    assert child.stdout.strip() == "survived"


# --- robustness: construction ----------------------------------------------------------------


@pytest.mark.parametrize(
    ("nodes", "message"),
    [
        (np.full((10, 2), 5.0), "zero length"),
        (np.array([[0.0, 0.0], [10.0, 0.0]]), "shape"),
        (np.zeros((10, 3)), "shape"),
        (np.zeros(10), "shape"),
        ([], "shape"),
        (np.where(np.arange(2 * N).reshape(N, 2) == 7, np.nan, initial()), "finite"),
        (np.where(np.arange(2 * N).reshape(N, 2) == 7, np.inf, initial()), "finite"),
        ("a circle", "nodes"),
        (np.array([[100.0, 200.0], [300.0, 200.0], [500.0, 200.0]]), "no area"),
        (circle_nodes((60.0, 40.0), 0.01, 64), "no area"),
        (circle_nodes((60.0, 40.0), 30.0, 4097), "at most 4096 nodes"),
    ],
    ids=[
        "identical",
        "two nodes",
        "3 columns",
        "1-D",
        "empty",
        "NaN",
        "inf",
        "text",
        "on a line",
        "within a pixel",
        "too many nodes",
    ],
)
def test_bad_contours_are_rejected(nodes: Any, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Tracker(nodes)
    tracker = Tracker(initial())
    with pytest.raises(ValueError, match=message):
        tracker.reset(nodes)
    np.testing.assert_array_equal(tracker.nodes, resample(initial(), N))  # unchanged


def test_unknown_option_is_rejected() -> None:
    with pytest.raises(ValueError, match="warp_speed"):
        Tracker(initial(), warp_speed=9)


def test_unknown_option_message_lists_the_valid_ones() -> None:
    with pytest.raises(ValueError, match="warp_speed") as caught:
        TrackerOptions.from_mapping({"warp_speed": 9, "search_radius": 8})
    for field in dataclasses.fields(TrackerOptions):
        assert field.name in str(caught.value)
    assert TrackerOptions.from_mapping({"search_radius": 8}).search_radius == 8


def test_open_contours_are_rejected() -> None:
    with pytest.raises(ValueError, match="closed"):
        Tracker(initial(), closed=False)


BAD_OPTIONS: list[tuple[str, Any]] = [
    ("stiffness", 0.0),
    ("stiffness", -1.0),
    ("stiffness", math.nan),
    ("stiffness", math.inf),
    ("stiffness", "stiff"),
    ("stiffness", True),
    ("search_radius", 0),
    ("search_radius", 2.5),
    ("search_radius", True),
    ("search_radius", "12"),
    ("iterations", 0),
    ("iterations", -3),
    ("tolerance", -0.1),
    ("tolerance", math.nan),
    ("region_weight", -1.0),
    ("edge_weight", math.nan),
    ("distance_penalty", "high"),
    ("band", 0),
    ("band", None),
    ("learning_rate", -0.1),
    ("learning_rate", 1.5),
    ("learning_rate", math.nan),
    ("learning_rate", "fast"),
    ("learning_rate", None),
    ("max_features", 0),
    ("tie", 1.5),
    ("tie", -0.1),
    ("robust_scale", -1.0),
    ("cut_band", -1),
    ("cut_band", 65),
    ("cut_band", 8.0),
    ("cut_band", True),
    ("reacquire_above", -0.1),
    ("reacquire_above", 1.5),
    ("reacquire_above", math.nan),
    ("hold_below", -0.1),
    ("hold_below", 2.0),
    ("hold_below", "some"),
    ("far_background", -0.1),
    ("far_background", 1.5),
    ("far_background", math.inf),
    ("far_background", "all"),
    ("rigid_behind", 1),
    ("rigid_behind", "yes"),
    ("revealed_background", 0),
    ("revealed_background", None),
    ("bridge_strips", 1),
    ("bridge_strips", "no"),
    ("carve_gaps", 1.0),
    ("carve_gaps", "yes"),
    ("full_resolution_edges", 0),
    ("full_resolution_edges", "true"),
    ("align_prediction", 1),
    ("align_prediction", None),
    ("turn_outline", 0),
    ("turn_outline", "on"),
    ("colour_bits", 0),
    ("colour_bits", 6),
    ("colour_bits", 5.0),
    ("colour_bits", True),
    ("colour_bits", "5"),
]


@pytest.mark.parametrize(("name", "value"), BAD_OPTIONS, ids=[f"{n}={v!r}" for n, v in BAD_OPTIONS])
def test_bad_option_values_are_rejected_naming_the_option(name: str, value: Any) -> None:
    with pytest.raises(ValueError, match=name):
        Tracker(initial(), **{name: value})


ODD_OPTIONS: list[tuple[str, Any]] = [
    ("flow_stiffness", math.inf),
    ("stiffness", 1e300),
    ("stiffness", 1e-300),
    ("search_radius", 40_000),
    ("region_weight", math.inf),
    ("edge_weight", math.inf),
    ("distance_penalty", math.inf),
    ("tolerance", math.inf),
]


@pytest.mark.parametrize(("name", "value"), ODD_OPTIONS, ids=[f"{n}={v!r}" for n, v in ODD_OPTIONS])
def test_accepted_options_never_break_step(name: str, value: Any, frames: list[U8]) -> None:
    """An option value is either rejected up front or tracking works with it."""
    message = ""
    try:
        tracker = Tracker(initial(), **{name: value})
    except ValueError as exc:
        message = str(exc)
    if message:
        assert name in message
        return
    for frame in frames[:3]:
        result = tracker.step(frame)
        check_result(result)


# --- robustness: random small frames ---------------------------------------------------------


@st.composite
def small_frames(draw: st.DrawFn) -> list[U8]:
    """1-4 random uint8 frames, up to 40 x 40, grey or 1, 3 or 4 channels; mostly one shape."""

    def shape() -> tuple[int, ...]:
        h, w = draw(st.integers(1, 40)), draw(st.integers(1, 40))
        channels = draw(st.sampled_from([None, 1, 3, 4]))
        return (h, w) if channels is None else (h, w, channels)

    first = shape()
    sequence: list[U8] = []
    for _ in range(draw(st.integers(1, 4))):
        this = shape() if draw(st.integers(0, 3)) == 0 else first
        sequence.append(draw(arrays(np.uint8, this, elements=st.integers(0, 255))))
    return sequence


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    sequence=small_frames(),
    x=st.floats(-20, 60),
    y=st.floats(-20, 60),
    radius=st.floats(1.0, 30),  # a triangle of radius 1 encloses 1.3 px²; less is refused
    count=st.integers(3, 40),
)
def test_random_small_frames_never_break_the_tracker(
    sequence: list[U8], x: float, y: float, radius: float, count: int
) -> None:
    tracker = Tracker(circle_nodes((x, y), radius, count))
    for frame in sequence:
        step_or_reject(tracker, frame, count)
    assert np.isfinite(tracker.nodes).all()
    restored = Tracker.from_state(through_json(tracker.to_state()))
    np.testing.assert_allclose(restored.nodes, tracker.nodes, atol=0.1)
