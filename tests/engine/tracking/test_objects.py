"""engine.tracking.ObjectsTracker: several objects through the same frames, by id."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, mask_to_contour
from engine.testing.crowd import make_crowd
from engine.tracking import ObjectResult, ObjectsTracker, Tracker, label_mask

CROWD = make_crowd(seed=0, length=20)
COUNT = len(CROWD.masks)


def overlapping() -> set[int]:
    """Objects whose masks meet another's in some frame."""
    found = set()
    for a in range(COUNT):
        for b in range(a + 1, COUNT):
            if any((ma & mb).any() for ma, mb in zip(CROWD.masks[a], CROWD.masks[b], strict=True)):
                found |= {a, b}
    return found


@pytest.mark.parametrize("workers", [1, 2])
def test_eight_objects_keep_their_ids_and_their_outlines(workers: int) -> None:
    assert COUNT == 8
    assert overlapping()  # the scene has objects crossing each other
    tracker = ObjectsTracker(
        {f"o{k}": mask_to_contour(CROWD.masks[k][0], 64) for k in range(COUNT)}, workers=workers
    )
    ious = np.zeros((COUNT, len(CROWD.frames)))
    for t, frame in enumerate(CROWD.frames):
        results = tracker.step(frame)
        assert [r.id for r in results] == [f"o{k}" for k in range(COUNT)]
        for k, r in enumerate(results):
            ious[k, t] = mask_iou(
                contour_to_mask(r.contours[0], frame.shape[:2]), CROWD.masks[k][t]
            )
    tracker.close()  # ends the pool of threads (none with one worker) ...
    tracker.close()
    assert len(tracker.step(CROWD.frames[-1])) == COUNT  # ... made again when needed
    mean = ious[:, 1:].mean(axis=1)
    # every object keeps its own identity: its track overlaps its own mask, not a neighbour's
    assert (ious[:, -1] > 0.5).all()
    free = [k for k in range(COUNT) if k not in overlapping()]
    assert (mean[free] >= 0.95).all()
    assert (mean >= 0.9).all()  # the one behind another keeps its outline under it


def test_objects_are_added_corrected_and_removed_between_frames() -> None:
    frames = CROWD.frames
    tracker = ObjectsTracker({"a": mask_to_contour(CROWD.masks[0][0], 48)})
    tracker.step(frames[0])
    tracker.add("b", mask_to_contour(CROWD.masks[2][1], 48))
    assert [r.id for r in tracker.step(frames[1])] == ["a", "b"]
    tracker.replace("a", mask_to_contour(CROWD.masks[0][2], 48))  # a correction
    results = tracker.step(frames[2])
    assert (
        mask_iou(contour_to_mask(results[0].contours[0], frames[2].shape[:2]), CROWD.masks[0][2])
        > 0.95
    )
    tracker.remove("b")
    assert [r.id for r in tracker.step(frames[3])] == ["a"]
    with pytest.raises(ValueError, match="exists"):
        tracker.add("a", circle_nodes((50, 50), 10, 16))
    with pytest.raises(KeyError):
        tracker.remove("zz")
    with pytest.raises(ValueError, match="at most 1"):
        ObjectsTracker(
            {"x": circle_nodes((50, 50), 10, 16), "y": circle_nodes((90, 50), 10, 16)},
            max_objects=1,
        )


@pytest.mark.parametrize("workers", [1, 2])
def test_a_restart_on_the_last_frame_is_as_if_the_outline_had_been_given_before_it(
    workers: int,
) -> None:
    """The snap's second look: the outline is corrected on the frame just tracked."""
    frames = CROWD.frames
    outlines = {f"o{k}": mask_to_contour(CROWD.masks[k][0], 48) for k in range(3)}
    given = ObjectsTracker(outlines, workers=workers)
    wrong = dict(outlines, o1=circle_nodes((60, 60), 12, 48))
    restarted = ObjectsTracker(wrong, workers=workers)
    given.step(frames[0])
    restarted.step(frames[0])
    restarted.restart("o1", outlines["o1"], frames[0])
    for frame in frames[1:4]:
        for a, b in zip(given.step(frame), restarted.step(frame), strict=True):
            assert a.id == b.id
            np.testing.assert_array_equal(a.contours[0], b.contours[0])
    with pytest.raises(KeyError):
        restarted.restart("nobody", outlines["o1"], frames[3])
    with pytest.raises(ValueError, match="N >= 3"):
        restarted.restart("o1", [[0.0, 0.0]], frames[3])
    np.testing.assert_array_equal(
        restarted.contours("o1")[0], given.contours("o1")[0]
    )  # a refused restart changes nothing


def test_an_object_in_pieces_gives_its_contours() -> None:
    pieces = [circle_nodes((100, 100), 20, 32), circle_nodes((200, 100), 15, 24)]
    tracker = ObjectsTracker({"kite": pieces, "surfer": circle_nodes((300, 300), 25, 40)})
    first = tracker.step(CROWD.frames[0])
    assert [len(r.contours) for r in first] == [2, 1]
    for r in first:  # what the tracker holds is what it answered
        for held, answered in zip(tracker.contours(r.id), r.contours, strict=True):
            np.testing.assert_array_equal(held, answered)
    with pytest.raises(KeyError):
        tracker.contours("nobody")


def test_bad_frames_move_no_object() -> None:
    tracker = ObjectsTracker({"a": circle_nodes((100, 100), 20, 32)})
    with pytest.raises(ValueError, match="uint8"):
        tracker.step(np.zeros((50, 50), np.float32))


def test_the_object_in_front_wins_an_overlap_else_the_more_confident() -> None:
    shape = (100, 100)
    a = ObjectResult("a", [circle_nodes((40, 50), 20, 32)], 0.9, "tracking")
    b = ObjectResult("b", [circle_nodes((60, 50), 20, 32)], 0.6, "tracking")
    labels = label_mask([a, b], shape)
    assert labels[50, 50] == 1  # both cover it, neither is known to be behind: the surer one
    assert labels[50, 75] == 2
    assert labels[5, 5] == 0
    assert label_mask([b, a], shape)[50, 50] == 2  # the order does not matter
    behind = ObjectResult("a", a.contours, 0.9, "tracking", behind=("b",))
    assert label_mask([behind, b], shape)[50, 50] == 2  # b is in front, though less sure
    assert label_mask([behind, b], shape)[50, 25] == 1


def test_an_objects_state_resumes_exactly() -> None:
    import json

    tracker = ObjectsTracker(
        {
            1: mask_to_contour(CROWD.masks[0][0], 48),
            "two": [circle_nodes((300, 300), 20, 32), circle_nodes((350, 300), 15, 24)],
        }
    )
    for frame in CROWD.frames[:3]:
        tracker.step(frame)
    resumed = ObjectsTracker.from_state(json.loads(json.dumps(tracker.to_state())))
    for frame in CROWD.frames[3:6]:
        a, b = tracker.step(frame), resumed.step(frame)
        assert [r.id for r in a] == [r.id for r in b] == [1, "two"]
        for x, y in zip(a, b, strict=True):
            for cx, cy in zip(x.contours, y.contours, strict=True):
                np.testing.assert_array_equal(cx, cy)


def test_an_objects_state_keeps_the_options_for_the_objects_added_after_it() -> None:
    import json

    options: dict[str, Any] = {"cut_band": 4, "lighting": False}
    tracker = ObjectsTracker({1: mask_to_contour(CROWD.masks[0][0], 48)}, **options)
    for frame in CROWD.frames[:2]:
        tracker.step(frame)
    resumed = ObjectsTracker.from_state(json.loads(json.dumps(tracker.to_state())))
    assert resumed.options == options
    outline = circle_nodes((300, 300), 20, 32)
    for t in (tracker, resumed):
        t.add(2, outline)
    added = resumed.trackers[2]
    assert isinstance(added, Tracker)
    assert added.options.cut_band == 4
    assert added.options.lighting is False
    for frame in CROWD.frames[2:4]:
        for x, y in zip(tracker.step(frame), resumed.step(frame), strict=True):
            for cx, cy in zip(x.contours, y.contours, strict=True):
                np.testing.assert_array_equal(cx, cy)


def test_an_objects_state_from_before_the_options_were_kept_resumes_on_the_defaults() -> None:
    tracker = ObjectsTracker({1: mask_to_contour(CROWD.masks[0][0], 48)})
    tracker.step(CROWD.frames[0])
    state = tracker.to_state()
    del state["options"]
    assert ObjectsTracker.from_state(state).options == {}


@pytest.mark.parametrize(
    "options", [["cut_band"], {"cut_band": -1}, {"no_such_option": 1}, {1: True}]
)
def test_an_objects_state_with_bad_options_is_refused(options: object) -> None:
    state = ObjectsTracker().to_state()
    state["options"] = options
    with pytest.raises(ValueError, match="option"):
        ObjectsTracker.from_state(state)


@pytest.mark.parametrize(
    "state",
    [
        {},
        {"kind": "objects"},
        {"kind": "objects", "objects": [[1]]},
        {"kind": "pieces"},
        {"kind": "objects", "objects": [], "in_front": [[1, 2]]},
        {"kind": "objects", "objects": [], "in_front": {"1": 2}},
        {"kind": "objects", "objects": [], "in_front": [[1]]},
        {"kind": "objects", "objects": [[{"id": 1}, {}]]},
        {"kind": "objects", "objects": [[[1, {"id": 1}], {}]]},
        {"kind": "objects", "objects": [], "in_front": [[{"id": 1}, 2]]},
        {"kind": "objects", "objects": [[1, {"kind": "neural"}]]},
    ],
)
def test_malformed_objects_states_are_refused(state: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="object"):
        ObjectsTracker.from_state(state)


def test_the_frame_is_checked_and_converted_once_and_each_object_tracks_as_well_as_alone(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import engine.tracking._frames as frames
    import engine.tracking.tracker as tracker_module

    starts = {k: mask_to_contour(CROWD.masks[k][0], 64) for k in (0, 3)}
    alone = {k: Tracker(nodes) for k, nodes in starts.items()}
    together = ObjectsTracker(starts)
    calls = []
    convert = frames.as_frame

    def counted(frame: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        calls.append(1)
        return convert(frame)

    monkeypatch.setattr(frames, "as_frame", counted)
    monkeypatch.setattr(tracker_module, "_as_frame", counted)  # a Tracker's own step
    for frame in CROWD.frames[:6]:
        calls.clear()
        results = together.step(frame)
        assert len(calls) == 1  # not once per object
        for k, r in zip(starts, results, strict=True):
            # the background's motion and the flow are measured once over the frame, not
            # around each contour: the same outline, not necessarily to the bit
            shape = frame.shape[:2]
            one = contour_to_mask(alone[k].step(frame).nodes, shape)
            assert mask_iou(contour_to_mask(r.contours[0], shape), one) > 0.97


@pytest.mark.parametrize(
    ("image", "grey"),
    [
        (np.zeros((40, 60, 3), np.uint8), np.zeros((40, 61), np.uint8)),  # sizes differ
        (np.zeros((40, 60, 3), np.float32), np.zeros((40, 60), np.uint8)),  # not uint8
        (np.zeros((40, 60, 4), np.uint8), np.zeros((40, 60), np.uint8)),  # BGRA, unconverted
        (np.zeros((40, 60, 3), np.uint8), np.zeros((40, 60, 3), np.uint8)),  # grey not H x W
    ],
)
def test_a_prepared_frame_that_is_not_one_is_refused(image: np.ndarray, grey: np.ndarray) -> None:
    tracker = Tracker(circle_nodes((30, 20), 10, 16))
    with pytest.raises(ValueError, match="step_prepared"):
        tracker.step_prepared(image, grey)
    assert tracker.frame_index == -1  # nothing moved


def test_an_object_around_the_whole_frame_hides_no_other() -> None:
    """A contour with no node in the frame is reported lost; it is in front of nothing,
    and the other objects track as if it were not there."""
    crowd = make_crowd(seed=1, count=3, length=12, size=(120, 160))
    starts = {k: mask_to_contour(crowd.masks[k][0], 32) for k in range(3)}

    def last(extra: dict[int, Any]) -> dict[Any, ObjectResult]:
        tracker = ObjectsTracker({**starts, **extra})
        results: list[ObjectResult] = []
        for frame in crowd.frames:
            results = tracker.step(frame)
        return {r.id: r for r in results}

    alone = last({})
    around = last({9: circle_nodes((80.0, 60.0), 400.0, 16)})
    assert around[9].status == "lost"
    for key in starts:
        assert around[key].behind == alone[key].behind
        assert np.array_equal(around[key].contours[0], alone[key].contours[0])
