"""engine.tracking.covering: an object behind another keeps its outline under it."""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np
import pytest

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.testing.crowd import make_crowd
from engine.tracking import ObjectsTracker, Tracker
from engine.tracking.covering import (
    NEUTRAL,
    RegionProbability,
    Silhouette,
    cover_maps,
    covered_share,
    fronts,
    in_front,
)
from engine.tracking.maps import Maps
from engine.tracking.motion import estimate_motion
from engine.tracking.shared import Crowd

# seed 0 of the crowd: object 5 passes in front of object 4 from frame 14 on, hiding up to
# about 70 % of it
CROWD = make_crowd(seed=0, length=32)
BACK, FRONT = 4, 5


def _ious(results: list[list[np.ndarray]], key: int) -> np.ndarray:
    shape = CROWD.frames[0].shape[:2]
    return np.array(
        [
            mask_iou(contour_to_mask(contours[0], shape), CROWD.masks[key][t])
            for t, contours in enumerate(results)
        ]
    )


def test_the_object_behind_keeps_its_outline_and_knows_what_is_in_front() -> None:
    starts = {k: mask_to_contour(CROWD.masks[k][0], 64) for k in (BACK, FRONT)}
    together = ObjectsTracker(starts)
    alone = Tracker(starts[BACK])
    tracked: dict[Hashable, list[list[np.ndarray]]] = {BACK: [], FRONT: []}
    on_its_own, behind = [], []
    for frame in CROWD.frames:
        results = together.step(frame)
        for r in results:
            tracked[r.id].append(r.contours)
        behind.append(results[0].behind)
        on_its_own.append([alone.step(frame).nodes])
    covered = [
        t for t in range(len(CROWD.frames)) if (CROWD.masks[BACK][t] & CROWD.masks[FRONT][t]).any()
    ]
    assert len(covered) > 10
    # the front object's colours show over the overlap: it is found in front, every frame
    assert all(behind[t] == (FRONT,) for t in covered[1:])
    assert all(behind[t] == () for t in range(covered[0]))
    assert _ious(tracked[FRONT], FRONT)[1:].min() > 0.95
    ours = _ious(tracked[BACK], BACK)
    # alone, the tracker shrinks onto the visible part (the front object's edge is the
    # nearest boundary); told what is in front, it keeps the whole outline
    assert _ious(on_its_own, BACK)[covered].mean() < 0.7
    assert ours[covered].mean() > 0.9
    assert ours[1:].min() > 0.8


def test_fronts_follow_the_colours_of_the_overlap() -> None:
    shape = (60, 80)
    left = Silhouette.of([circle_nodes((30, 30), 15, 32)], shape)
    right = Silhouette.of([circle_nodes((50, 30), 15, 32)], shape)
    far = Silhouette.of([circle_nodes((70, 50), 5, 16)], shape)
    assert left is not None
    assert right is not None
    assert far is not None
    assert far.overlap(left) is None

    def looks(right: float, left: float) -> RegionProbability:
        def probability(key: Hashable, box: tuple[int, int, int, int]) -> np.ndarray:
            x0, y0, x1, y1 = box
            return np.full((y1 - y0, x1 - x0), right if key == "right" else left, np.float32)

        return probability

    objects: dict[Hashable, Silhouette] = {"left": left, "right": right, "far": far}
    found, order = fronts(objects, looks(right=0.9, left=0.2))
    assert found == {"left": ["right"], "right": [], "far": []}
    assert order == {frozenset(("left", "right")): "right"}
    # alike colours: the order found when the overlap began is kept ...
    assert fronts(objects, looks(right=0.5, left=0.55), order)[1] == order
    assert fronts(objects, looks(right=0.5, left=0.55))[0]["right"] == ["left"]  # (afresh)
    # ... until the shared pixels clearly look like the other object
    assert fronts(objects, looks(right=0.3, left=0.8), order)[0]["right"] == ["left"]
    # a pair apart is forgotten
    apart: dict[Hashable, Silhouette] = {"left": left, "far": far}
    assert fronts(apart, looks(right=0.9, left=0.2), order)[1] == {}
    nothing = np.zeros((2, 2), bool)
    assert in_front(np.zeros((2, 2), np.float32), np.ones((2, 2), np.float32), nothing) is None


@pytest.mark.parametrize("edge_step", [1, 2])
def test_covered_pixels_are_neutral_and_still_seen(edge_step: int) -> None:
    probability = np.full((20, 30), 0.9, np.float32)
    edges = np.ones((20 // edge_step, 30 // edge_step), np.float32)
    motion = np.full((20, 30), 3.0, np.float32)
    maps = Maps((10, 5), probability, edges, edge_step, motion=motion)
    covered = np.zeros((40, 60), bool)
    covered[5:15, 10:20] = True  # the region's top-left 10 x 10 pixels
    out = cover_maps(maps, covered)
    assert (out.probability[:10, :10] == NEUTRAL).all()
    assert (out.probability[10:, :] == 0.9).all()
    assert (out.probability[:, 10:] == 0.9).all()
    assert out.observed is not None
    assert (out.observed == 0.9).all()
    assert out.motion is not None
    assert (out.motion[:10, :10] == 1.0).all()
    assert (out.motion[10:] == 3.0).all()
    assert (out.edges[: 10 // edge_step, : 10 // edge_step] == 0).all()
    assert (out.edges[10 // edge_step :] == 1).all()
    assert cover_maps(maps, None) is maps
    assert cover_maps(maps, np.zeros((40, 60), bool)) is maps  # nothing covered there


def test_covered_share_and_a_mostly_hidden_object_stays_put() -> None:
    frame = CROWD.frames[0]
    grey = np.ascontiguousarray(frame[..., 1])
    nodes = mask_to_contour(CROWD.masks[0][0], 64)
    hidden = CROWD.masks[0][0] > 0
    assert covered_share(None, nodes) == 0.0
    assert covered_share(hidden, nodes) > 0.95
    moved = np.roll(grey, 3, axis=1)
    assert np.linalg.norm(estimate_motion(grey, moved, nodes).matrix[:, 2]) > 2
    still = estimate_motion(grey, moved, nodes, covered=hidden)
    np.testing.assert_array_equal(still.matrix, np.eye(2, 3))


def test_a_tracker_told_nothing_is_covered_tracks_as_alone() -> None:
    nodes = mask_to_contour(CROWD.masks[0][0], 64)
    a, b = Tracker(nodes), Tracker(nodes)
    nothing = np.zeros(CROWD.frames[0].shape[:2], bool)
    for frame in CROWD.frames[:4]:
        grey = np.ascontiguousarray(frame.mean(axis=2).astype(np.uint8))
        np.testing.assert_array_equal(
            a.step_prepared(frame, grey).nodes, b.step_prepared(frame, grey, Crowd(nothing)).nodes
        )
    with pytest.raises(ValueError, match="covered"):
        a.step_prepared(frame, grey, Crowd(nothing[:-1]))
    with pytest.raises(ValueError, match="covered"):
        a.step_prepared(frame, grey, Crowd(nothing.astype(np.uint8)))


def test_a_session_resumes_exactly_mid_overlap() -> None:
    import json

    starts = {k: mask_to_contour(CROWD.masks[k][0], 64) for k in (BACK, FRONT)}
    tracker = ObjectsTracker(starts)
    for frame in CROWD.frames[:18]:  # the two overlap from frame 14 on
        tracker.step(frame)
    state = json.loads(json.dumps(tracker.to_state()))
    assert state["in_front"] == [[FRONT, BACK]]
    resumed = ObjectsTracker.from_state(state)
    for frame in CROWD.frames[18:22]:
        a, b = tracker.step(frame), resumed.step(frame)
        assert [r.behind for r in a] == [r.behind for r in b] == [(FRONT,), ()]
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x.contours[0], y.contours[0])
    # an object removed (or corrected) takes its overlap orders with it
    tracker.remove(FRONT)
    assert tracker.to_state()["in_front"] == []
    ObjectsTracker.from_state(json.loads(json.dumps(tracker.to_state())))
