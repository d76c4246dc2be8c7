"""engine.tracking.snap: a rough box or outline becomes the object's mask."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, mask_iou
from engine.tracking.snap import snap
from tests.engine.scenes import DiscScene, two_colour_frame

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
