"""engine.tracking.shared: the whole frame's background motion and flow, measured once."""

from __future__ import annotations

import numpy as np

from engine.geometry import circle_nodes, contour_to_mask
from engine.testing.crowd import make_crowd
from engine.tracking import Tracker
from engine.tracking.shared import Crowd, SharedMotion

SHIFT = (3, -2)  # the camera pans: everything moves 3 px right and 2 px up


def _panned() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    noise = rng.integers(0, 255, (60, 80)).astype(np.float32)
    import cv2

    texture = cv2.resize(noise, (400, 300), interpolation=cv2.INTER_CUBIC)
    previous = np.clip(texture, 0, 255).astype(np.uint8)
    current = np.roll(previous, (SHIFT[1], SHIFT[0]), axis=(0, 1))
    return previous, current, np.zeros(previous.shape, bool)


def test_the_background_and_the_flow_follow_a_pan() -> None:
    previous, current, excluded = _panned()
    # an object that stays put is left out of the background's fit
    disc = contour_to_mask(circle_nodes((200, 150), 40, 64), previous.shape) > 0
    current = current.copy()
    current[disc] = previous[disc]
    excluded |= disc
    shared = SharedMotion.measure(previous, current, excluded)
    assert shared.background is not None
    np.testing.assert_allclose(shared.background[:, :2], np.eye(2), atol=0.01)
    np.testing.assert_allclose(shared.background[:, 2], SHIFT, atol=0.2)
    assert shared.flow is not None
    # the flow (DIS, ultrafast, half resolution) is read at points away from the disc and
    # the borders: a pixel or so off each, the pan in the median
    xs, ys = np.meshgrid(np.arange(60, 340, 10.0), np.arange(60, 240, 10.0))
    grid = np.column_stack([xs.ravel(), ys.ravel()])
    far = grid[np.hypot(*(grid - [200, 150]).T) > 60]
    flow = shared.flow.at(far)
    np.testing.assert_allclose(np.median(flow, axis=0), SHIFT, atol=0.3)
    assert np.percentile(np.linalg.norm(flow - SHIFT, axis=1), 90) < 1.5
    assert shared.applies_to(previous, current)
    assert shared.applies_to(previous.copy(), current)  # equal frames, after a restore
    assert not shared.applies_to(current, current)
    assert not shared.applies_to(previous, current.copy())  # only the frame measured on
    assert not shared.applies_to(None, current)


def test_a_tracker_measures_its_own_when_shared_motion_is_of_other_frames() -> None:
    crowd = make_crowd(seed=1, length=4)
    grey = [np.ascontiguousarray(f.mean(axis=2).astype(np.uint8)) for f in crowd.frames]
    from engine.geometry import mask_to_contour

    nodes = mask_to_contour(crowd.masks[0][0], 64)
    plain, given = Tracker(nodes), Tracker(nodes)
    previous, current, excluded = _panned()
    stale = SharedMotion.measure(previous, current, excluded)  # other frames entirely
    for frame, g in zip(crowd.frames, grey, strict=True):
        np.testing.assert_array_equal(
            plain.step_prepared(frame, g).nodes,
            given.step_prepared(frame, g, Crowd(shared=stale)).nodes,
        )
