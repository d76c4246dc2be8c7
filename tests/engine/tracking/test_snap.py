"""engine.tracking.snap: a rough box or outline becomes the object's mask."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, mask_iou
from engine.tracking.snap import snap
from tests.engine.scenes import DiscScene, decoy_scene, two_colour_frame

U8 = NDArray[np.uint8]
CENTRE, RADIUS = (80.0, 60.0), 25.0
SCENE = DiscScene(width=320, height=240, radius=40.0, seed=2)


def tight_box(mask: U8) -> tuple[int, int, int, int]:
    """The box of a mask in pixel edges."""
    ys, xs = np.nonzero(mask)
    return int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1


def test_a_tight_box_snaps_onto_a_flat_disc() -> None:
    frame = two_colour_frame(CENTRE, RADIUS)
    truth = two_colour_truth()
    found = snap(frame, tight_box(truth))
    assert found.dtype == np.uint8
    assert set(np.unique(found)) <= {0, 255}
    assert mask_iou(found, truth) > 0.9


def two_colour_truth() -> U8:
    from tests.engine.scenes import disc_mask

    return disc_mask(CENTRE, RADIUS, (120, 160))


def test_a_rough_box_snaps_onto_a_textured_disc_on_texture() -> None:
    centre = (150.0, 110.0)
    truth = SCENE.mask(centre)
    x0, y0, x1, y1 = tight_box(truth)
    found = snap(SCENE.frame(centre), (x0 - 6, y0 - 4, x1 + 5, y1 + 7))
    assert mask_iou(found, truth) > 0.85


def test_a_loose_polygon_snaps_and_nothing_outside_it_is_taken() -> None:
    frame = two_colour_frame(CENTRE, RADIUS)
    loose = circle_nodes(CENTRE, RADIUS + 12.0, 48)
    found = snap(frame, loose)
    assert mask_iou(found, two_colour_truth()) > 0.9
    from engine.geometry import contour_to_mask

    outside = contour_to_mask(loose, found.shape) == 0
    assert not found[outside].any()


def test_a_box_on_a_grey_frame_and_one_reaching_past_the_edges() -> None:
    frame = two_colour_frame(CENTRE, RADIUS)
    grey = frame[..., 1].copy()
    assert mask_iou(snap(grey, tight_box(two_colour_truth())), two_colour_truth()) > 0.8
    past = snap(frame, (-50, -50, 400, 400))  # the whole frame: still an answer
    assert past.shape == (120, 160)
    assert past.any()


@pytest.mark.parametrize("box", [(-1e9, -1e9, 1e9, 1e9), (0, 0, 1e300, 1e300)])
def test_a_box_far_beyond_the_frame_still_gives_an_answer(box: tuple[float, ...]) -> None:
    """Past what OpenCV can draw (its coordinates are int32 sixteenths): the frame, not an
    OpenCV error."""
    found = snap(two_colour_frame(CENTRE, RADIUS), box)
    assert found.shape == (120, 160)
    assert found.all()


def test_a_featureless_box_still_gives_a_contour_to_start_from() -> None:
    flat = np.full((100, 100, 3), 128, np.uint8)
    found = snap(flat, (20, 30, 60, 70))
    assert found.any()
    ys, xs = np.nonzero(found)
    assert xs.min() >= 20
    assert xs.max() < 60
    assert ys.min() >= 30
    assert ys.max() < 70


def test_a_large_object_at_480p_is_solved_on_the_shrunk_region() -> None:
    """The coarse solve is right on a large region (its time is the snap benchmark's)."""
    scene = DiscScene(width=854, height=480, radius=150.0, seed=4)
    truth = scene.mask((420.0, 240.0))
    found = snap(scene.frame((420.0, 240.0)), tight_box(truth))
    assert mask_iou(found, truth) > 0.85


def stick_scene() -> tuple[U8, U8]:
    """A red disc with a 3 px stick reaching the right of its box, on green (small-scale sizes)."""
    rng = np.random.default_rng(3)
    frame = np.clip(rng.normal((150, 170, 90), 12, (120, 200, 3)), 0, 255).astype(np.uint8)
    truth = np.zeros((120, 200), np.uint8)
    cv2.circle(truth, (60, 60), 25, 255, -1)
    cv2.rectangle(truth, (80, 59), (150, 61), 255, -1)
    red = np.clip(rng.normal((60, 50, 170), 12, frame.shape), 0, 255).astype(np.uint8)
    frame[truth > 0] = red[truth > 0]
    return frame, truth


def test_the_tightness_prior_brings_back_a_thin_end_the_cut_dropped() -> None:
    """Every column of the box meets the object: the stick's columns get a pin each."""
    from engine.tracking._grabcut import grabcut
    from engine.tracking.snap import ITERATIONS, _tighten

    frame, truth = stick_scene()
    x0, y0, x1, y1 = tight_box(truth)
    box = np.zeros(truth.shape, np.uint8)
    box[y0:y1, x0:x1] = 1
    start = np.where(box > 0, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
    cut = grabcut(frame, start, ITERATIONS)
    assert cut is not None
    stick = truth.copy()
    stick[:, :90] = 0
    dropped = replace(cut, labels=np.where(stick > 0, cv2.GC_PR_BGD, cut.labels).astype(np.uint8))
    assert not dropped.found[stick > 0].any()
    found, resumed = _tighten(frame, box, dropped)
    assert found[stick > 0].mean() > 0.9
    assert (resumed.labels == cv2.GC_FGD).any()  # the cut it came from holds the pins
    assert mask_iou(found, truth) > 0.95


def test_the_tightness_prior_pins_nothing_on_the_background_of_a_loose_box(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Rows and columns of a loose box that hold only background colours stay empty."""
    from engine.tracking import snap as module
    from engine.tracking._grabcut import grabcut
    from engine.tracking.snap import ITERATIONS, _tighten

    monkeypatch.setattr(module, "STRAY_SHARE", 0.0)  # a pin would stay, as a stray

    frame, truth = stick_scene()
    x0, y0, x1, y1 = tight_box(truth)
    box = np.zeros(truth.shape, np.uint8)
    box[y0 - 15 : y1 + 15, x0 - 20 : x1 + 20] = 1
    start = np.where(box > 0, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
    cut = grabcut(frame, start, ITERATIONS)
    assert cut is not None
    assert mask_iou(cut.found, truth) > 0.9
    found, same = _tighten(frame, box, cut)
    np.testing.assert_array_equal(found, cut.found)
    assert same is cut


def test_strays_are_pins_that_joined_nothing() -> None:
    from engine.tracking.snap import _without_strays

    before = np.zeros((40, 40), np.uint8)
    before[5:25, 5:25] = 1
    after = before.copy()
    after[30, 30] = 1  # a pin alone: dropped
    after[5:25, 26:28] = 1  # new, but 2 % of the object: kept
    after[24:26, 24:26] = 1  # grown onto the old piece: kept
    kept = _without_strays(after, before)
    assert kept[30, 30] == 0
    assert kept[5:25, 26:28].all()
    assert kept[25, 25] == 1


def test_the_next_frame_drops_a_still_patch_of_the_objects_colours() -> None:
    first, second, truth, patch = decoy_scene()
    box = tight_box(truth)
    alone = snap(first, box)
    assert (alone[patch] > 0).mean() > 0.9  # colour alone takes the patch in
    assert mask_iou(alone, truth) < 0.95
    moving = snap(first, box, next_frame=second)
    assert (moving[patch] > 0).mean() < 0.1
    assert mask_iou(moving, truth) > 0.98


def test_a_next_frame_where_nothing_moved_changes_nothing() -> None:
    first, _, truth, _ = decoy_scene()
    box = tight_box(truth)
    np.testing.assert_array_equal(snap(first, box, next_frame=first), snap(first, box))
    grey = np.asarray(cv2.cvtColor(first, cv2.COLOR_BGR2GRAY), np.uint8)  # grey is as good
    np.testing.assert_array_equal(snap(first, box, next_frame=grey), snap(first, box))


def test_with_the_next_frame_nothing_outside_a_loose_outline_is_taken() -> None:
    from engine.geometry import contour_to_mask

    first, second, truth, _ = decoy_scene()
    loose = circle_nodes((120.0, 90.0), 52.0, 48)
    found = snap(first, loose, next_frame=second)
    assert not found[contour_to_mask(loose, found.shape) == 0].any()
    assert mask_iou(found, truth) > 0.8


def test_a_bad_next_frame_is_refused() -> None:
    frame = two_colour_frame(CENTRE, RADIUS)
    box = tight_box(two_colour_truth())
    with pytest.raises(ValueError, match="next_frame"):
        snap(frame, box, next_frame=np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(ValueError, match="next_frame"):
        snap(frame, box, next_frame=frame.astype(np.float32))


def test_the_cut_of_grabcuts_energy_reproduces_grabcut_and_takes_more_evidence() -> None:
    """With no extra odds the one cut gives GrabCut's own labels; strong odds move pixels,
    but never the definite ones."""
    from engine.tracking._grabcut import cut_with_odds, grabcut

    frame, truth = stick_scene()
    x0, y0, x1, y1 = tight_box(truth)
    start = np.full(truth.shape, cv2.GC_BGD, np.uint8)
    start[y0:y1, x0:x1] = cv2.GC_PR_FGD
    start[60, 60] = cv2.GC_FGD
    cut = grabcut(frame, start, 3)
    assert cut is not None
    none = np.zeros(truth.shape)
    same = cut_with_odds(frame, cut, none)
    assert np.mean(same == cut.found) > 0.999
    extra = none.copy()
    extra[50:70, 50:70] = -1e3  # the disc's centre, the pin among it
    extra[y0 : y0 + 5, x1 - 5 : x1] = 1e3  # background inside the box
    extra[:5, :5] = 1e3  # outside the box: definite background
    moved = cut_with_odds(frame, cut, extra)
    assert moved[60, 60] == 1
    assert moved[50:70, 50:70].sum() == 1
    assert moved[y0 : y0 + 5, x1 - 5 : x1].all()
    assert not moved[:5, :5].any()


@pytest.mark.parametrize(
    ("outline", "message"),
    [
        ((10, 10, 5, 20), "x1 > x0"),
        ((10, 10, 10, 20), "x1 > x0"),
        ((0, 0, float("nan"), 5), "finite"),
        ((500, 500, 600, 600), "outside the frame"),
        ([[0, 0], [1, 1]], "N >= 3"),
        ((1, 2, 3), "shape|points"),
    ],
)
def test_bad_outlines_are_refused(outline: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        snap(two_colour_frame(CENTRE, RADIUS), outline)  # type: ignore[arg-type]


def test_bad_images_are_refused() -> None:
    with pytest.raises(ValueError, match="uint8"):
        snap(np.zeros((10, 10, 3), np.float32), (1, 1, 5, 5))
    with pytest.raises(ValueError, match="channels"):
        snap(np.zeros((10, 10, 4), np.uint8), (1, 1, 5, 5))
