"""engine.tracking.holding: nodes with no colour step across them hold the shape."""

from __future__ import annotations

import numpy as np
import pytest

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.testing.synthetic import make_sequence
from engine.tracking import Tracker
from engine.tracking.holding import carry, carry_by_shape, hold_factors, side_contrast


def test_side_contrast_sees_a_step_and_no_step() -> None:
    nodes = circle_nodes((50.0, 50.0), 20.0, 64)
    inside = contour_to_mask(nodes, (100, 100)) > 0
    probability = np.where(inside, 0.9, 0.1).astype(np.float32)
    probability[:, 60:] = 0.9  # on the right the background looks like the object
    contrast = side_contrast(probability, (0, 0), nodes)
    left = nodes[:, 0] < 40
    right = nodes[:, 0] > 68
    assert contrast[left].min() > 0.7
    assert np.abs(contrast[right]).max() < 0.05
    # the region may sit anywhere in the frame
    shifted = side_contrast(probability, (10, 5), nodes + np.array([10.0, 5.0]))
    np.testing.assert_allclose(shifted, contrast)


def test_hold_factors() -> None:
    contrast = np.array([-0.3, 0.0, 0.1, 0.2, 0.8])
    np.testing.assert_allclose(hold_factors(contrast, 0.2), [1.0, 1.0, 0.5, 0.0, 0.0])
    np.testing.assert_array_equal(hold_factors(contrast, 0.0), np.zeros(5))


def test_carry_follows_the_nodes_whatever_their_order() -> None:
    source = circle_nodes((0.0, 0.0), 10.0, 16)
    values = np.linspace(0.0, 1.0, 16)
    target = np.roll(source[::-1], 5, axis=0) + 0.2
    carried = carry(values, source, target)
    np.testing.assert_allclose(carried, np.roll(values[::-1], 5))
    assert carry(values, source[:8], target).tolist() == [0.0] * 16  # mismatched: nothing known


def test_a_hold_pattern_goes_with_a_contour_found_elsewhere() -> None:
    source = circle_nodes((100.0, 80.0), 30.0, 64)
    held = np.zeros(64)
    held[:16] = 1.0  # a quarter of the contour held
    found = np.roll(source, 3, axis=0) + np.array([250.0, -40.0])  # re-acquired far away
    np.testing.assert_array_equal(carry_by_shape(held, source, found), np.roll(held, 3))


@pytest.mark.parametrize("seed", [0, 1])
def test_a_stretch_without_contrast_holds_its_shape(seed: int) -> None:
    """The background next to part of the outline has the object's very colour."""
    clip = make_sequence("no_contrast_stretch", seed=seed, length=12)
    start = mask_to_contour(clip.masks[0], 128)
    held, free = Tracker(start, hold_below=0.6), Tracker(start, hold_below=0.0)
    for frame in clip.frames:
        a, b = held.step(frame), free.step(frame)
    last = clip.masks[-1]
    assert mask_iou(contour_to_mask(a.nodes, last.shape), last) >= 0.93
    assert mask_iou(contour_to_mask(b.nodes, last.shape), last) < 0.8  # it leaks without
