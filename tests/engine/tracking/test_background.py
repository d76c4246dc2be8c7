"""engine.tracking.background and the figure-ground split of the object's motion."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

import engine
from engine.geometry import circle_nodes, contour_to_mask
from engine.tracking.background import background_motion, frame_background
from engine.tracking.motion import FramePair, estimate_motion
from tests.engine.scenes import shifted, textured_frame

U8 = NDArray[np.uint8]
W, H = 320, 240
CENTRE, RADIUS = (140.0, 120.0), 30.0
DISC = circle_nodes(CENTRE, RADIUS, 64)


def grey(seed: int) -> U8:
    return np.asarray(cv2.cvtColor(textured_frame(seed, H, W), cv2.COLOR_BGR2GRAY), np.uint8)


def scene(move: tuple[float, float], pan: tuple[float, float]) -> tuple[U8, U8]:
    """A textured disc on textured ground; then the disc moved by ``move``, the view by ``pan``."""
    ground, disc = grey(5), grey(6)
    before = np.where(contour_to_mask(DISC, (H, W)) > 0, disc, ground)
    moved = contour_to_mask(DISC + move, (H, W)) > 0
    after = np.where(moved, shifted(disc, *move), shifted(ground, *pan))
    return np.asarray(before, np.uint8), np.asarray(after, np.uint8)


@pytest.mark.parametrize("coarse", [False, True])
@pytest.mark.parametrize("origin", [(0, 0), (60, 40), (61, 41)])
def test_the_background_motion_is_measured_outside_the_contour(
    origin: tuple[int, int], coarse: bool
) -> None:
    before, after = scene((6.0, 0.0), (-3.0, 2.0))
    x0, y0 = origin
    found = background_motion(before[y0:, x0:], after[y0:, x0:], DISC, origin, coarse=coarse)
    assert found is not None
    # frame coordinates whatever the region: a point of the ground moves by the pan
    point = np.array([250.0, 60.0])
    np.testing.assert_allclose(
        found[:, :2] @ point + found[:, 2], point + np.array([-3.0, 2.0]), atol=0.3
    )


def test_a_flat_background_has_no_measurable_motion() -> None:
    flat = np.full((H, W), 128, np.uint8)
    for coarse in (False, True):
        assert background_motion(flat, flat, DISC, coarse=coarse) is None
        assert background_motion(flat[:1], flat[:1], DISC, coarse=coarse) is None
        assert background_motion(flat[:3, :3], flat[:3, :3], DISC, coarse=coarse) is None


def test_the_whole_frame_background_leaves_the_objects_out() -> None:
    # a large disc (a third of the frame, richer in corners than the ground) moves against
    # the view: fitted with it, the "background" would follow the disc
    big = circle_nodes((160.0, 120.0), 80.0, 128)
    move, pan = (7.0, -4.0), (-3.0, 2.0)
    ground, disc = grey(5), np.asarray(np.clip(grey(6).astype(int) * 2 - 128, 0, 255), np.uint8)
    inside = contour_to_mask(big, (H, W)) > 0
    before = np.where(inside, disc, ground).astype(np.uint8)
    moved = contour_to_mask(big + move, (H, W)) > 0
    after = np.where(moved, shifted(disc, *move), shifted(ground, *pan)).astype(np.uint8)
    found = frame_background(before, after, inside)
    assert found is not None
    np.testing.assert_allclose(found[:, :2], np.eye(2), atol=0.01)
    np.testing.assert_allclose(found[:, 2], pan, atol=0.3)
    # the halved frames, given, are those it would halve itself
    whole = FramePair.whole(before, after)
    given = frame_background(before, after, inside, (whole.half_previous, whole.half_current))
    np.testing.assert_array_equal(given, found)
    with_disc = frame_background(before, after, np.zeros((H, W), bool))
    assert with_disc is None or not np.allclose(with_disc[:, 2], pan, atol=0.3)


def test_a_flat_or_tiny_frame_has_no_whole_frame_background() -> None:
    flat = np.full((H, W), 128, np.uint8)
    assert frame_background(flat, flat, np.zeros((H, W), bool)) is None
    assert frame_background(flat[:3], flat[:3], np.zeros((3, W), bool)) is None


def test_points_moving_with_the_background_are_left_out_of_the_object_motion() -> None:
    # the contour took in more panning ground than disc: without the split the ground's
    # corners outvote the disc's and the "object" moves with the view
    move, pan = (6.0, 0.0), (-3.0, 2.0)
    before, after = scene(move, pan)
    greedy = circle_nodes((CENTRE[0] + 8.0, CENTRE[1]), RADIUS + 10.0, 64)
    held = estimate_motion(before, after, greedy)
    split = estimate_motion(before, after, greedy, figure_ground=True)
    centre = np.array(CENTRE)
    np.testing.assert_allclose(held.apply(centre[None])[0], centre + np.array(pan), atol=1.5)
    np.testing.assert_allclose(split.apply(centre[None])[0], centre + np.array(move), atol=1.0)
    assert split.inlier_ratio > 0.5  # the share of the object's points that agree


def test_an_object_moving_with_the_background_keeps_all_its_points() -> None:
    # a passenger carried along with the view: every point moves "with the background"
    before, after = scene((-3.0, 2.0), (-3.0, 2.0))
    split = estimate_motion(before, after, DISC, figure_ground=True)
    np.testing.assert_allclose(split.matrix[:, 2], [-3.0, 2.0], atol=0.3)
    np.testing.assert_allclose(split.matrix[:, :2], np.eye(2), atol=0.01)
    assert split.inlier_ratio > 0.9


def test_a_state_from_before_the_split_resumes_without_it() -> None:
    """Tracker states whose options lack ``figure_ground`` continue exactly as before it."""
    # the disc moving against a panning view, the contour holding some ground
    frames = [scene((6.0 * k, 0.0), (-3.0 * k, 2.0 * k))[1] for k in range(8)]
    shots = [np.asarray(cv2.cvtColor(f, cv2.COLOR_GRAY2BGR), np.uint8) for f in frames]
    greedy = circle_nodes((CENTRE[0] + 8.0, CENTRE[1]), RADIUS + 10.0, 64)
    old_style = engine.Tracker(greedy, figure_ground=False)
    new_style = engine.Tracker(greedy)
    for shot in shots[:4]:
        old_style.step(shot)
        new_style.step(shot)
    state = json.loads(json.dumps(old_style.to_state()))
    del state["options"]["figure_ground"]
    restored = engine.Tracker.from_state(state)
    assert restored.options.figure_ground is False
    for shot in shots[4:]:
        want, got, other = old_style.step(shot), restored.step(shot), new_style.step(shot)
        np.testing.assert_array_equal(got.nodes, want.nodes)
        assert not np.array_equal(other.nodes, want.nodes)  # the split is at work here


def test_figure_ground_must_be_a_bool() -> None:
    with pytest.raises(ValueError, match="figure_ground must be true or false"):
        engine.Tracker(DISC, figure_ground=1)
