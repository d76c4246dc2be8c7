"""The occlusion rule: covered pixels, and whether something foreign is in front."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.maps import Maps
from engine.tracking.occlusion import MIN_PIECE, NEUTRAL, foreign, unoccluded

U8 = NDArray[np.uint8]
H, W = 120, 160
CENTRE, RADIUS = (80.0, 60.0), 40.0
GREY, RED, GREEN = (128, 128, 128), (40, 40, 200), (40, 200, 40)  # BGR


def scene(bar: tuple[int, int, int]) -> tuple[U8, NDArray[np.bool_], NDArray[np.bool_]]:
    """A red disc on grey, a bar of colour ``bar`` across it; the bar's part in the disc covered."""
    silhouette = contour_to_mask(circle_nodes(CENTRE, RADIUS, 64), (H, W)) > 0
    image = np.empty((H, W, 3), np.uint8)
    image[:] = GREY
    image[silhouette] = RED
    image[:, 70:80] = bar
    covered = silhouette.copy()
    covered[:, :70] = False
    covered[:, 80:] = False
    return image, covered, silhouette


def test_a_bar_unlike_the_surroundings_is_foreign() -> None:
    image, covered, silhouette = scene(GREEN)
    assert foreign(image, (0, 0), covered, silhouette)


def test_background_uncovered_by_the_object_is_not_foreign() -> None:
    """What a limb uncovers has the colours of the ring round the object."""
    image, covered, silhouette = scene(GREY)
    assert not foreign(image, (0, 0), covered, silhouette)


def test_pieces_smaller_than_the_least_judged_are_not_foreign() -> None:
    image, _, silhouette = scene(GREEN)
    specks = np.zeros((H, W), np.bool_)
    specks[30:90:6, 72:78:3] = True  # scattered single pixels, each its own piece
    assert specks.sum() >= MIN_PIECE  # enough pixels in all, none large enough
    assert not foreign(image, (0, 0), specks, silhouette)
    assert not foreign(image, (0, 0), np.zeros((H, W), np.bool_), silhouette)


def test_foreign_reads_the_region_at_its_origin_and_grey_frames() -> None:
    for bar, expected in ((GREEN, True), (GREY, False)):
        image, covered, silhouette = scene(bar)
        big = np.zeros((H + 20, W + 30, 3), np.uint8)
        big[:] = GREY
        big[20:, 30:] = image
        assert foreign(big, (30, 20), covered, silhouette) is expected
    _, covered, silhouette = scene(GREEN)
    grey = np.full((H, W), 128, np.uint8)
    grey[silhouette] = 60
    grey[:, 70:80] = 250
    assert foreign(grey, (0, 0), covered, silhouette)


@pytest.mark.parametrize(
    ("origin", "shape"),
    [((0, 0), (H, W - 1)), ((1, 0), (H, W)), ((0, -1), (H, W))],
    ids=["shapes-differ", "past-the-right", "above-the-top"],
)
def test_foreign_rejects_a_region_it_cannot_read(
    origin: tuple[int, int], shape: tuple[int, int]
) -> None:
    image, covered, _ = scene(GREEN)
    with pytest.raises(ValueError, match="region"):
        foreign(image, origin, covered, np.zeros(shape, np.bool_))


def test_unoccluded_says_when_the_object_is_behind_something_foreign() -> None:
    image, covered, silhouette = scene(GREEN)
    probability = np.where(silhouette, 0.9, 0.1).astype(np.float32)
    probability[covered] = 0.1  # the bar looks like background now
    maps = Maps((0, 0), probability, np.zeros((H, W), np.float32))
    was = np.where(silhouette, 255, 0).astype(np.uint8)  # it was the object's before
    still = (np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), circle_nodes(CENTRE, RADIUS, 64))
    refine, remember = unoccluded(maps, ((0, 0), was), still, image)
    assert refine.in_front
    assert not remember.in_front
    assert np.all(refine.probability[covered] == NEUTRAL)
    assert np.all(remember.probability[covered] == 1.0)
    uncovered, _ = unoccluded(maps, ((0, 0), was), still, scene(GREY)[0])
    assert not uncovered.in_front
    unjudged, _ = unoccluded(maps, ((0, 0), was), still)
    assert not unjudged.in_front
    assert np.array_equal(unjudged.probability, refine.probability)


def _mean_iou(rigid_behind: bool) -> float:
    clip = make_sequence("occluder", seed=4)
    tracker = Tracker(mask_to_contour(clip.masks[0], 128), rigid_behind=rigid_behind)
    ious = []
    for frame, mask in zip(clip.frames, clip.masks, strict=True):
        nodes = tracker.step(frame).nodes
        ious.append(mask_iou(contour_to_mask(nodes, mask.shape), mask > 0))
    return float(np.mean(ious[1:-1]))


def test_a_bar_sweeping_across_the_object_does_not_drag_the_contour_along() -> None:
    """Synthetic ``occluder``, seed 4: the bar enters over the object's rim.

    Bent by the dense flow next to the bar, the contour went with the bar and kept
    only the part on one side of it (0.66); moved rigidly while the bar is in front,
    it keeps the whole object.
    """
    assert _mean_iou(rigid_behind=True) >= 0.95
    assert _mean_iou(rigid_behind=False) < 0.8


def test_with_the_option_off_no_colours_are_judged(monkeypatch: pytest.MonkeyPatch) -> None:
    """``rigid_behind=False`` is the tracker before it: not even the test runs."""
    import engine.tracking.occlusion as occlusion

    def judged(*_: object) -> bool:
        raise AssertionError("the covered pieces were judged")

    monkeypatch.setattr(occlusion, "foreign", judged)
    clip = make_sequence("occluder", seed=4, length=12)
    tracker = Tracker(mask_to_contour(clip.masks[0], 64), rigid_behind=False)
    for frame in clip.frames:
        tracker.step(frame)
    tracker = Tracker(mask_to_contour(clip.masks[0], 64))  # on: judged once the bar is in
    with pytest.raises(AssertionError, match="judged"):
        _ = [tracker.step(frame) for frame in clip.frames]
