"""engine.tracking.working: frames larger than the working resolution are tracked downscaled."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
from engine.testing.crowd import make_crowd
from engine.tracking import ObjectsTracker, PiecesTracker, Tracker, working
from engine.tracking._frames import as_frame
from engine.tracking.working import (
    WORKING_SIDE,
    WorkingFrames,
    WorkingScale,
    downscale,
    working_scale,
)
from tests.engine.tracking.moving_disc import (
    H,
    W,
    assert_same,
    initial,
    larger,
    resumes_alike,
    run,
    through_json,
    upscaled,
)

U8 = NDArray[np.uint8]
F64 = NDArray[np.float64]
UP = 2
GRID_H, GRID_W = 480, 640
"""The working grid of the generated crowd drawn up by :data:`UP`."""
"""The moving disc's frames drawn twice as large: tracked on a working grid of their
original size (``working_side=H``), they are the original clip, give or take the resize."""


@pytest.mark.parametrize(
    ("shape", "side", "size"),
    [
        ((720, 1280), 480, (853, 480)),  # a 720p camera
        ((1080, 1920, 3), 480, (853, 480)),
        ((1920, 1080), 480, (480, 853)),  # portrait: the shorter side is the width
        ((2160, 3840), 480, (853, 480)),
        ((240, 400), 120, (200, 120)),
    ],
)
def test_frames_above_the_working_side_are_brought_down_to_it(
    shape: tuple[int, ...], side: int, size: tuple[int, int]
) -> None:
    scale = working_scale(shape, side)
    assert scale is not None
    assert scale.size == size
    assert scale.frame_shape == shape[:2]


@pytest.mark.parametrize(
    ("shape", "side"), [((480, 854), 480), ((120, 200), 480), ((720, 1280), 0)]
)
def test_frames_at_or_below_the_working_side_or_side_0_are_tracked_as_they_are(
    shape: tuple[int, int], side: int
) -> None:
    assert working_scale(shape, side) is None


def test_points_map_pixel_centres_as_opencv_resizes() -> None:
    scale = working_scale((720, 1280), 480)
    assert scale is not None
    # the frame's outer edges (pixel -1/2 and size - 1/2) are the grid's
    edges = np.array([[-0.5, -0.5], [1279.5, 719.5]])
    np.testing.assert_allclose(scale.to_working(edges), [[-0.5, -0.5], [852.5, 479.5]])
    points = np.random.default_rng(0).uniform(0, 700, (50, 2))
    np.testing.assert_allclose(scale.to_frame(scale.to_working(points)), points, atol=1e-9)
    # a bright pixel's centre lands where the resized image is brightest
    frame = np.zeros((720, 1280), np.uint8)
    frame[300:306, 600:606] = 255
    small = scale.image(frame)
    ys, xs = np.nonzero(small == small.max())
    centre = scale.to_working(np.array([[602.5, 302.5]]))[0]
    assert abs(xs.mean() - centre[0]) < 0.6
    assert abs(ys.mean() - centre[1]) < 0.6


def test_downscale_halves_exactly_then_interpolates() -> None:
    rng = np.random.default_rng(1)
    image = rng.integers(0, 256, (1080, 1920, 3), dtype=np.uint8)
    out = downscale(image, (853, 480))
    assert out.shape == (480, 853, 3)
    assert out.dtype == np.uint8
    # an exact halving is the 2 x 2 mean, as INTER_AREA gives it
    half = downscale(image, (960, 540))
    means = image.reshape(540, 2, 960, 2, 3).astype(np.float64).mean(axis=(1, 3))
    assert np.abs(half - means).max() <= 0.5 + 1e-9
    flat = np.full((720, 1280), 77, np.uint8)
    assert (downscale(flat, (853, 480)) == 77).all()


@pytest.mark.parametrize("shape", [(1080, 1920), (1079, 1919), (1081, 1921), (721, 1281)])
def test_a_blob_lands_where_its_points_map_on_even_and_odd_frames(
    shape: tuple[int, int],
) -> None:
    """Found by a review: an odd side halved lost its last line and, with it, about a frame
    pixel at the far corner (0.44 working pixels)."""
    scale = working_scale(shape, 480)
    assert scale is not None
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    for x, y in ((30.0, 30.0), (w - 40.0, h - 40.0)):
        blob = (200 * np.exp(-((xs - x) ** 2 + (ys - y) ** 2) / 72.0)).astype(np.uint8)
        small = scale.image(blob).astype(np.float64)
        sy, sx = np.mgrid[0 : small.shape[0], 0 : small.shape[1]]
        found = np.array([(small * sx).sum(), (small * sy).sum()]) / small.sum()
        np.testing.assert_allclose(found, scale.to_working(np.array([[x, y]]))[0], atol=0.05)


def test_a_mask_counts_working_pixels_at_least_half_covered() -> None:
    scale = working_scale((8, 8), 4)
    assert scale is not None
    assert scale.size == (4, 4)
    mask = np.zeros((8, 8), np.bool_)
    mask[0, 0:2] = True  # half of working pixel (0, 0)
    mask[2, 2] = True  # a quarter of working pixel (1, 1)
    out = scale.mask(mask)
    assert out.dtype == np.bool_
    assert out.shape == (4, 4)
    assert out[0, 0]
    assert not out[1, 1]
    assert out.sum() == 1


@pytest.mark.parametrize("side", [-1, 1, 63, 16385, 480.0, True, "480", None])
def test_a_bad_working_side_is_refused(side: Any) -> None:
    with pytest.raises(ValueError, match="working_side must be 0 or an integer"):
        Tracker(initial(), working_side=side)


def test_the_default_is_480_lines() -> None:
    assert Tracker(initial()).options.working_side == WORKING_SIDE == 480


def test_a_large_frame_is_tracked_on_the_working_grid_as_the_small_one(
    frames: list[U8],
) -> None:
    small = run(Tracker(initial()), frames)
    tracker = Tracker(larger(initial()), working_side=H)
    big = run(tracker, [upscaled(f) for f in frames])
    previous = tracker.previous_frame
    assert previous is not None
    assert previous.shape == (H, W)
    for a, b in zip(small, big, strict=True):
        # in the large frame's pixels, where the small track is, give or take the resize
        shape = (H * UP, W * UP)
        overlap = mask_iou(contour_to_mask(larger(a.nodes), shape), contour_to_mask(b.nodes, shape))
        assert overlap > 0.95
    np.testing.assert_allclose(tracker.nodes, big[-1].nodes)
    assert big[0].nodes == pytest.approx(larger(initial()))  # the first frame: as given


def test_without_a_working_side_the_frame_is_tracked_as_it_is(frames: list[U8]) -> None:
    tracker = Tracker(larger(initial()), working_side=0)
    run(tracker, [upscaled(f) for f in frames[:2]])
    previous = tracker.previous_frame
    assert previous is not None
    assert previous.shape == (H * UP, W * UP)


def test_a_frame_of_another_size_restarts_on_its_own_grid(frames: list[U8]) -> None:
    tracker = Tracker(larger(initial()), working_side=H)
    run(tracker, [upscaled(f) for f in frames[:3]])
    here = tracker.nodes
    # the same pixels of a frame as large again: the contour stays, the grid changes
    result = tracker.step(upscaled(frames[3], 4))
    np.testing.assert_allclose(result.nodes, here, atol=1e-9)
    previous = tracker.previous_frame
    assert previous is not None
    assert previous.shape == (H, W)
    # then a frame at the working size itself: tracked as it is
    result = tracker.step(frames[4])
    np.testing.assert_allclose(result.nodes, here, atol=1e-9)
    assert tracker.previous_frame is not None
    assert tracker.previous_frame.shape == (H, W)


def test_a_state_on_the_working_grid_resumes_exactly(frames: list[U8]) -> None:
    big = [upscaled(f) for f in frames[:10]]
    tracker = Tracker(larger(initial()), working_side=H)
    run(tracker, big[:5])
    state = through_json(tracker.to_state())
    assert state["frame_shape"] == [H * UP, W * UP]
    expected = run(tracker, big[5:])
    restored = Tracker.from_state(state)
    np.testing.assert_array_equal(restored.nodes, Tracker.from_state(state).nodes)
    for a, b in zip(run(restored, big[5:]), expected, strict=True):
        assert_same(a, b)


def test_a_state_without_its_frame_keeps_the_contour_in_frame_pixels(frames: list[U8]) -> None:
    tracker = Tracker(larger(initial()), working_side=H)
    run(tracker, [upscaled(f) for f in frames[:3]])
    state = through_json(tracker.to_state(include_frame=False))
    assert "frame_shape" not in state
    restored = Tracker.from_state(state)
    np.testing.assert_allclose(restored.nodes, tracker.nodes, atol=1e-9)
    result = restored.step(upscaled(frames[3]))  # a first frame again: as given
    np.testing.assert_allclose(result.nodes, tracker.nodes, atol=1e-9)


def test_a_state_from_before_the_working_resolution_resumes_at_full_resolution(
    frames: list[U8],
) -> None:
    big = [upscaled(f) for f in frames[:6]]
    tracker = Tracker(larger(initial()), working_side=0)
    run(tracker, big[:3])
    state = through_json(tracker.to_state())
    del state["options"]["working_side"], state["frame_shape"]
    assert resumes_alike(tracker, state, big[3:]).options.working_side == 0


@pytest.mark.parametrize(
    "frame_shape", [[240], [240, 0], ["240", 400], [240.0, 400], 7, [480, 900]]
)
def test_a_state_with_a_bad_frame_shape_is_refused(frame_shape: Any, frames: list[U8]) -> None:
    tracker = Tracker(larger(initial()), working_side=H)
    run(tracker, [upscaled(f) for f in frames[:2]])
    state = through_json(tracker.to_state())
    state["frame_shape"] = frame_shape  # [480, 900]: a grid of 200 x 120 is not that frame's
    with pytest.raises(ValueError, match="malformed tracker state"):
        Tracker.from_state(state)


def test_several_objects_on_large_frames_are_tracked_in_frame_pixels() -> None:
    crowd = make_crowd(seed=3, count=3, length=8)
    frames = [upscaled(f) for f in crowd.frames]
    shape = frames[0].shape[:2]
    masks = [
        [cv2.resize(m, shape[::-1], interpolation=cv2.INTER_NEAREST) for m in object_masks]
        for object_masks in crowd.masks
    ]
    tracker = ObjectsTracker({k: mask_to_contour(masks[k][0], 64) for k in range(3)})
    overlaps = np.zeros((3, len(frames)))
    for t, frame in enumerate(frames):
        for k, r in enumerate(tracker.step(frame)):  # in the order the objects were given
            assert r.id == k
            overlaps[k, t] = mask_iou(contour_to_mask(r.contours[0], shape), masks[k][t])
    assert (overlaps[:, 1:].mean(axis=1) >= 0.9).all()


def large_crowd(length: int) -> tuple[list[U8], dict[int, F64]]:
    """Three generated objects drawn up to 960 x 1280 (a 480 x 640 working grid), and their
    first contours."""
    crowd = make_crowd(seed=3, count=3, length=length)
    frames = [upscaled(f) for f in crowd.frames]
    shape = frames[0].shape[:2]
    starts = {
        k: mask_to_contour(cv2.resize(crowd.masks[k][0], shape[::-1], interpolation=0), 64)
        for k in range(3)
    }
    return frames, starts


def counting_downscale(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Count the frames brought down to a working grid."""
    calls: list[int] = []
    real = working.downscale

    def counted(image: U8, size: tuple[int, int]) -> U8:
        calls.append(1)
        return real(image, size)

    monkeypatch.setattr(working, "downscale", counted)
    return calls


def test_one_working_grid_a_frame_serves_every_tracker_stepping_on_it() -> None:
    frame = upscaled(make_crowd(seed=3, count=1, length=1).frames[0])
    image, grey = as_frame(frame)
    scale = working_scale(grey.shape, WORKING_SIDE)
    assert scale is not None
    frames = WorkingFrames(image, grey)
    with ThreadPoolExecutor(4) as pool:
        grids = list(pool.map(lambda _: frames.at(scale, image, grey), range(8)))
    assert all(g is grids[0] for g in grids)  # one tuple: one image, grey and smoothing
    small, small_grey, smoothing = grids[0]
    want, want_grey = as_frame(downscale(image, scale.size))
    np.testing.assert_array_equal(small, want)
    np.testing.assert_array_equal(small_grey, want_grey)
    assert smoothing.of(small, small_grey) is small  # clean: the grid itself
    # another frame (not the one it was made for) is brought down anew, not mistaken for it
    other, other_grey = as_frame(np.ascontiguousarray(frame[:, ::-1]))
    flipped = frames.at(scale, other, other_grey)[0]
    np.testing.assert_array_equal(flipped, as_frame(downscale(other, scale.size))[0])


def test_a_working_grid_larger_than_the_frame_is_refused() -> None:
    image, grey = as_frame(np.zeros((240, 320, 3), np.uint8))
    too_large = WorkingScale((240, 320), (640, 480))  # a grid for another, larger frame
    with pytest.raises(ValueError, match="size must be"):
        WorkingFrames(image, grey).at(too_large, image, grey)


@pytest.mark.parametrize("pieces", [False, True])
def test_several_trackers_on_a_large_frame_bring_it_down_once_and_track_as_alone(
    monkeypatch: pytest.MonkeyPatch, pieces: bool
) -> None:
    frames, starts = large_crowd(5)

    def session() -> ObjectsTracker | PiecesTracker:
        if pieces:  # one object in three pieces
            return PiecesTracker(list(starts.values()))
        return ObjectsTracker(starts)

    def contours(found: Any) -> list[NDArray[np.float64]]:
        if pieces:
            return list(found.contours)
        return [c for r in found for c in r.contours]

    # each tracker making its own grid, as alone
    monkeypatch.setattr(WorkingFrames, "at", lambda self, s, i, g: working._grid(s, i))
    own = session()
    want = [contours(own.step(f)) for f in frames]
    monkeypatch.undo()
    calls = counting_downscale(monkeypatch)
    shared = session()
    for frame, expected in zip(frames, want, strict=True):
        calls.clear()
        got = contours(shared.step(frame))
        assert len(calls) == 1
        assert len(got) == len(expected)
        for a, b in zip(got, expected, strict=True):
            np.testing.assert_array_equal(a, b)


def test_objects_on_large_frames_read_the_motion_measured_once_on_the_grid(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """As on frames tracked as they are, the background's motion and the flow of the whole
    grid are measured once for the objects, which read them instead of measuring their own."""
    from engine.tracking.prediction import FlowMotion

    frames, starts = large_crowd(5)
    read: list[bool] = []
    predict = FlowMotion.predict

    def reading(self: FlowMotion, *args: Any, **kwargs: Any) -> Any:
        shared = kwargs.get("shared")
        read.append(shared is not None and shared.current.shape == (GRID_H, GRID_W))
        return predict(self, *args, **kwargs)

    monkeypatch.setattr(FlowMotion, "predict", reading)
    tracker = ObjectsTracker(starts)
    for frame in frames:
        tracker.step(frame)
    # the first frame starts them; from the second on each reads the grid's measures
    assert read == [True] * 3 * (len(frames) - 1)


def test_objects_on_large_frames_resume_from_a_state_exactly() -> None:
    """The session's last grid (what the shared motion is measured from) comes back with the
    objects' states: the resumed session measures, and tracks, as the one that went on."""
    frames, starts = large_crowd(6)
    tracker = ObjectsTracker(starts)
    for frame in frames[:3]:
        tracker.step(frame)
    resumed = ObjectsTracker.from_state(through_json(tracker.to_state()))
    for frame in frames[3:]:
        for a, b in zip(tracker.step(frame), resumed.step(frame), strict=True):
            assert (a.id, a.confidence) == (b.id, b.confidence)
            np.testing.assert_array_equal(a.contours[0], b.contours[0])


@pytest.mark.parametrize(("shape", "side"), [((0, 640), 480), ((480,), 480), ((720, 1280), -1)])
def test_working_scale_refuses_a_bad_shape_or_side(shape: tuple[int, ...], side: int) -> None:
    with pytest.raises(ValueError, match="must be"):
        working_scale(shape, side)


@pytest.mark.parametrize("size", [(0, 480), (853, 0), (1300, 480), (853, 800)])
def test_downscale_refuses_a_size_it_cannot_bring_the_image_down_to(
    size: tuple[int, int],
) -> None:
    with pytest.raises(ValueError, match="size must be"):
        downscale(np.zeros((720, 1280), np.uint8), size)
