"""engine.tracking.turn: the object's turn, for the remembered outline and its marks."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.geometry import circle_nodes, fit_similarity
from engine.tracking import Tracker
from engine.tracking.motion import FramePair, estimate_motion
from engine.tracking.shape_memory import marks_at
from engine.tracking.turn import measure_turn, turned

W, H, R = 240, 200, 50.0
CENTRE = (120.0, 100.0)
IDENTITY = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])

U8 = NDArray[np.uint8]


def _smooth_noise(seed: int, sigma: float, scale: float) -> NDArray[np.float32]:
    import cv2

    noise = np.random.default_rng(seed).normal(0.0, 1.0, (H, W)).astype(np.float32)
    smooth = np.asarray(cv2.GaussianBlur(noise, (0, 0), sigma), np.float32)
    result: NDArray[np.float32] = smooth * np.float32(scale / smooth.std())
    return result


TEXTURE = _smooth_noise(5, 4.0, 12.0)  # the object's faint texture, in its own coordinates
BACKGROUND = _smooth_noise(9, 3.0, 15.0) + np.float32(170.0)


def disc_frame(
    degrees: float, seed: int, centre: tuple[float, float] = CENTRE, texture: float = 1.0
) -> U8:
    """A grey frame: the textured disc turned by ``degrees`` (x towards y) about its
    centre, on a static textured background, with a sensor noise of 2 grey levels."""
    import cv2

    a = math.radians(degrees)
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float32)
    dx, dy = xs - np.float32(centre[0]), ys - np.float32(centre[1])
    u = (math.cos(a) * dx + math.sin(a) * dy + CENTRE[0]).astype(np.float32)
    v = (-math.sin(a) * dx + math.cos(a) * dy + CENTRE[1]).astype(np.float32)
    body = 70.0 + texture * cv2.remap(TEXTURE, u, v, cv2.INTER_LINEAR)
    image = np.where(dx * dx + dy * dy <= R * R, body, BACKGROUND)
    image = image + np.random.default_rng(seed).normal(0.0, 2.0, (H, W))
    return np.clip(np.round(image), 0, 255).astype(np.uint8)


def angle_of(matrix: NDArray[np.float64]) -> float:
    return math.degrees(math.atan2(matrix[1, 0], matrix[0, 0]))


@pytest.mark.parametrize("degrees", [1.0, 2.0, 3.0, -2.0])
def test_the_turn_is_measured_where_the_similarity_sees_less(degrees: float) -> None:
    """Lucas-Kanade sees the rim's points move only across it; the interior says more."""
    nodes = circle_nodes(CENTRE, R, 64)
    before, after = disc_frame(0.0, 0), disc_frame(degrees, 1)
    similarity = estimate_motion(before, after, nodes).matrix
    angle = measure_turn(before, after, nodes, similarity)
    assert angle is not None
    found = math.degrees(angle)
    assert abs(found - degrees) < 0.2  # 0.96, 1.90, 2.88 and -1.97 when written
    assert abs(found - degrees) < abs(angle_of(similarity) - degrees)  # it saw a fifth


def test_no_turn_without_anything_inside_to_follow() -> None:
    nodes = circle_nodes(CENTRE, R, 64)
    flat = disc_frame(0.0, 0, texture=0.0)
    flat[:] = np.where(flat > 120, 170, 70).astype(np.uint8)  # no noise, no texture
    assert measure_turn(flat, flat.copy(), nodes, IDENTITY) is None
    tiny = circle_nodes(CENTRE, 6.0, 16)  # nothing a window inside its rim
    assert measure_turn(disc_frame(0.0, 0), disc_frame(2.0, 1), tiny, IDENTITY) is None


def test_turned_keeps_the_scale_and_the_centroid_motion() -> None:
    nodes = circle_nodes((60.0, 40.0), 20.0, 32)
    c, s = 1.1 * math.cos(0.1), 1.1 * math.sin(0.1)
    matrix = np.array([[c, -s, 5.0], [s, c, -3.0]])
    result = turned(matrix, nodes, 0.3)
    assert math.isclose(math.atan2(result[1, 0], result[0, 0]), 0.3)
    assert math.isclose(float(np.hypot(result[0, 0], result[1, 0])), 1.1)
    centre = nodes.mean(axis=0)
    np.testing.assert_allclose(
        result[:, :2] @ centre + result[:, 2], matrix[:, :2] @ centre + matrix[:, 2]
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((np.zeros((10, 10), np.uint8), np.zeros((10, 12), np.uint8)), "one shape"),
        ((np.zeros((10, 10, 3), np.uint8), np.zeros((10, 10, 3), np.uint8)), "grey"),
    ],
)
def test_frames_must_be_grey_and_alike(args: tuple[U8, U8], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        measure_turn(*args, circle_nodes((5.0, 5.0), 3.0, 8), IDENTITY)


def test_nodes_and_matrix_are_checked() -> None:
    frame = disc_frame(0.0, 0)
    with pytest.raises(ValueError, match=r"\S"):
        measure_turn(frame, frame, np.array([[1.0, math.nan], [2.0, 3.0], [4.0, 1.0]]), IDENTITY)
    with pytest.raises(ValueError, match="2 x 3"):
        measure_turn(frame, frame, circle_nodes(CENTRE, R, 32), np.eye(3))
    with pytest.raises(ValueError, match="2 x 3"):
        measure_turn(frame, frame, circle_nodes(CENTRE, R, 32), np.full((2, 3), math.inf))


def test_marks_ride_on_the_outline() -> None:
    outline = circle_nodes((50.0, 50.0), 20.0, 32)
    marks = np.zeros(32)
    marks[:8] = 1.0  # a quarter of the outline was held on the first frame
    turn = np.array([[0.0, -1.0, 100.0], [1.0, 0.0, 0.0]])  # a quarter turn about (50, 50)
    turned_outline = outline @ turn[:, :2].T + turn[:, 2]
    nodes = circle_nodes((50.0, 50.0), 20.5, 64)  # the contour's nodes do not turn
    held = marks_at(nodes, turned_outline, marks)
    np.testing.assert_array_equal(
        held,
        marks[np.argmin(np.linalg.norm(nodes[:, None] - turned_outline[None], axis=2), axis=1)],
    )
    assert held.sum() == pytest.approx(16.0, abs=2.0)  # the same quarter, turned
    assert not np.array_equal(held, marks_at(nodes, outline, marks))
    with pytest.raises(ValueError, match="one per outline point"):
        marks_at(nodes, outline, marks[:-1])


def _outline_turn(tracker: Tracker, start: NDArray[np.float64]) -> float:
    outline = tracker._memory.outline
    assert outline is not None
    fit, _ = fit_similarity(start, outline)
    assert fit is not None
    return angle_of(fit)


def test_the_outline_turns_with_the_object() -> None:
    """A textured disc turning by 2 degrees a frame for 12 frames."""
    start = circle_nodes(CENTRE, R, 96)
    turning, carried = Tracker(start), Tracker(start, turn_outline=False)
    for i in range(13):
        frame = disc_frame(2.0 * i, i)
        turning.step(frame)
        carried.step(frame)
    assert abs(_outline_turn(turning, start) - 24.0) < 3.0
    assert abs(_outline_turn(carried, start) - 24.0) > abs(_outline_turn(turning, start) - 24.0)
    marks = turning._memory.marks
    assert marks is not None
    assert carried._memory.marks is None
    assert len(marks) == len(start)


def test_the_marks_are_part_of_the_state() -> None:
    tracker = Tracker(circle_nodes(CENTRE, R, 64))
    for i in range(4):
        tracker.step(disc_frame(2.0 * i, i))
    state = tracker.to_state()
    assert len(state["search"]["marks"]) == len(state["search"]["outline"])
    resumed = Tracker.from_state(state)
    for i in range(4, 8):
        frame = disc_frame(2.0 * i, i)
        np.testing.assert_array_equal(resumed.step(frame).nodes, tracker.step(frame).nodes)
    # written before the outline turned: continues as it was, marks on the nodes
    old = tracker.to_state()
    del old["options"]["turn_outline"]
    del old["search"]["marks"]
    restored = Tracker.from_state(old)
    assert not restored.options.turn_outline
    assert restored._memory.marks is None
    # the option off: marks in the state are not used
    unturned = tracker.to_state()
    unturned["options"]["turn_outline"] = False
    assert Tracker.from_state(unturned)._memory.marks is None
    # the shape memory off: no outline, so no marks
    off = tracker.to_state()
    off["options"]["shape_memory"] = False
    assert Tracker.from_state(off)._memory.marks is None


@pytest.mark.parametrize(
    "marks",
    [[0.5] * 3, [math.nan] * 64, [1.5] * 64, "marks", [[0.0, 1.0]] * 64],
    ids=["wrong length", "NaN", "above 1", "text", "pairs"],
)
def test_malformed_marks_are_refused(marks: object) -> None:
    tracker = Tracker(circle_nodes(CENTRE, R, 64))
    for i in range(2):
        tracker.step(disc_frame(2.0 * i, i))
    state = tracker.to_state()
    state["search"]["marks"] = marks
    with pytest.raises(ValueError, match="malformed tracker state"):
        Tracker.from_state(state)
    state = tracker.to_state()
    state["search"]["outline"] = None  # marks without an outline
    with pytest.raises(ValueError, match="marks need an outline"):
        Tracker.from_state(state)


def test_the_option_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="turn_outline must be true or false"):
        Tracker(circle_nodes((50.0, 50.0), 20.0, 32), turn_outline=1)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    width=st.integers(8, 90),
    height=st.integers(8, 90),
    box=st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 1), st.floats(0, 1)),
)
def test_the_interior_corners_are_those_of_the_whole_image(
    seed: int, width: int, height: int, box: tuple[float, float, float, float]
) -> None:
    """Sought in the interior's box only, the corners are the whole image's, in its order."""
    import cv2

    from engine.tracking.motion import CORNER_BLOCK, CORNER_QUALITY, CORNER_SPACING
    from engine.tracking.turn import INTERIOR_CORNERS, _interior_corners

    rng = np.random.default_rng(seed)
    noise = rng.normal(128.0, 40.0, (height, width)).astype(np.float32)
    grey = np.clip(cv2.GaussianBlur(noise, (0, 0), 1.2), 0, 255).astype(np.uint8)
    inner = np.zeros((height, width), np.uint8)  # any rectangle, up to the image's edges
    (a, b), (c, d) = (
        sorted((box[0] * width, box[1] * width)),
        sorted((box[2] * height, box[3] * height)),
    )
    inner[int(c) : int(d) + 1, int(a) : int(b) + 1] = 1
    whole = cv2.goodFeaturesToTrack(
        grey, INTERIOR_CORNERS, CORNER_QUALITY, CORNER_SPACING, mask=inner, blockSize=CORNER_BLOCK
    )
    found = _interior_corners(grey, inner)
    if whole is None:
        assert found is None
    else:
        assert found is not None
        np.testing.assert_array_equal(found, whole)


def test_the_prediction_crops_serve_the_turn() -> None:
    """Handed the motion's crops, the turn and the motion measure exactly as without them."""
    nodes = circle_nodes(CENTRE, R, 64)
    before, after = disc_frame(0.0, 0), disc_frame(2.0, 1)
    frames = FramePair.around(before, after, nodes)
    alone = estimate_motion(before, after, nodes)
    given = estimate_motion(before, after, nodes, frames=frames)
    np.testing.assert_array_equal(given.matrix, alone.matrix)
    angle = measure_turn(before, after, nodes, alone.matrix)
    assert angle is not None
    assert measure_turn(before, after, nodes, alone.matrix, frames=frames) == angle


@pytest.mark.parametrize("frames", [object(), (np.zeros((4, 4), np.uint8),) * 2, "crops"])
def test_crops_that_are_not_a_frame_pair_are_refused(frames: object) -> None:
    nodes = circle_nodes(CENTRE, R, 64)
    before, after = disc_frame(0.0, 0), disc_frame(2.0, 1)
    with pytest.raises(ValueError, match="FramePair"):
        estimate_motion(before, after, nodes, frames=frames)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="FramePair"):
        measure_turn(before, after, nodes, IDENTITY, frames=frames)  # type: ignore[arg-type]


def test_given_crops_are_used_as_they_are_and_none_are_made_anew() -> None:
    nodes = circle_nodes(CENTRE, R, 64)
    before, after = disc_frame(0.0, 0), disc_frame(2.0, 1)
    made = FramePair.around(before, after, nodes)
    assert FramePair.given(made, before, after, nodes) is made
    anew = FramePair.given(None, before, after, nodes)
    assert anew.origin == made.origin
    assert np.array_equal(anew.half_current, made.half_current)
    with pytest.raises(ValueError, match="FramePair or None; got tuple"):
        FramePair.given((before, after), before, after, nodes)
