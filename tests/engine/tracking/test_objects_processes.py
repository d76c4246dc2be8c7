"""ObjectsTracker(processes=True): the objects on worker processes, the same results bit for bit."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np
import pytest

from engine.geometry import mask_to_contour
from engine.testing.crowd import make_crowd
from engine.tracking import ObjectResult, ObjectsTracker

CROWD = make_crowd(seed=0, length=20)  # objects cross from frame 14 on: waves, covered masks
STARTS = {f"o{k}": mask_to_contour(masks[0], 48) for k, masks in enumerate(CROWD.masks)}


@pytest.fixture
def remote() -> Iterator[ObjectsTracker]:
    tracker = ObjectsTracker(STARTS, workers=2, processes=True)
    yield tracker
    tracker.close()


def same(a: list[ObjectResult], b: list[ObjectResult]) -> bool:
    """Equal results: ids, every contour's coordinates, confidence, status, depth."""
    return len(a) == len(b) and all(
        x.id == y.id
        and len(x.contours) == len(y.contours)
        and all(np.array_equal(p, q) for p, q in zip(x.contours, y.contours, strict=True))
        and (x.confidence, x.status, x.behind) == (y.confidence, y.status, y.behind)
        for x, y in zip(a, b, strict=True)
    )


@pytest.mark.parametrize("noise", [0.0, 12.0])
def test_objects_on_two_processes_track_exactly_as_in_this_one(
    remote: ObjectsTracker, noise: float
) -> None:
    # with noise, each worker smooths the frame itself for its objects, as this one does
    local = ObjectsTracker(STARTS)
    behind = 0
    rng = np.random.default_rng(7)
    for clean in CROWD.frames:
        frame = np.asarray(np.clip(clean + rng.normal(0.0, noise, clean.shape), 0, 255), np.uint8)
        here, there = local.step(frame), remote.step(frame)
        assert same(here, there)
        behind += sum(bool(r.behind) for r in here)
    assert behind  # the comparison covered objects tracked behind others
    assert remote.to_state() == local.to_state()


def test_objects_on_large_frames_track_on_processes_exactly_as_in_this_one() -> None:
    # 960 x 720: tracked on the 640 x 480 working grid, the whole frame's motion measured
    # there once and read by each worker's trackers from its own copy of the grid
    frames = [np.asarray(cv2.resize(f, None, fx=1.5, fy=1.5), np.uint8) for f in CROWD.frames]
    starts = {k: 1.5 * nodes + 0.25 for k, nodes in STARTS.items()}
    local = ObjectsTracker(starts)
    there = ObjectsTracker(starts, workers=2, processes=True)
    try:
        for frame in frames[:12]:
            assert same(local.step(frame), there.step(frame))
    finally:
        there.close()


def test_adding_correcting_and_removing_mid_stream_on_processes(remote: ObjectsTracker) -> None:
    local = ObjectsTracker(STARTS)

    def both(name: str, *args: Any) -> None:
        getattr(local, name)(*args)
        getattr(remote, name)(*args)

    for t, frame in enumerate(CROWD.frames[:8]):
        if t == 2:
            both("remove", "o3")
            both("add", "new", mask_to_contour(CROWD.masks[3][2], 40))
        if t == 4:
            both("replace", "o0", mask_to_contour(CROWD.masks[0][4], 40))
        if t == 5:  # an object in two pieces
            both("add", "pair", [STARTS["o5"] + [0.0, 0.0], STARTS["o6"] + [0.0, 0.0]])
        assert same(local.step(frame), remote.step(frame))
    assert list(remote.trackers) == list(local.trackers)
    assert [len(c) for c in remote.contours("pair")] == [48, 48]
    with pytest.raises(KeyError):
        remote.remove("o3")


def test_a_state_resumes_on_processes_exactly() -> None:
    local = ObjectsTracker(STARTS)
    for frame in CROWD.frames[:15]:
        local.step(frame)
    state = local.to_state()
    resumed = ObjectsTracker.from_state(state, workers=2, processes=True)
    try:
        assert resumed.to_state() == state
        for frame in CROWD.frames[15:]:
            assert same(local.step(frame), resumed.step(frame))
    finally:
        resumed.close()


def test_a_workers_error_is_raised_here_and_close_brings_the_objects_back(
    remote: ObjectsTracker,
) -> None:
    workers = remote._workers
    assert workers is not None
    with pytest.raises(ValueError, match="unknown message"):
        workers.call(0, ("nonsense",))
    workers.send(0, ("nonsense",))
    workers.send(1, ("nonsense",))
    with pytest.raises(ValueError, match="unknown message"):
        workers.gather([0, 1])  # both answers read: none is left for the next call
    local = ObjectsTracker(STARTS)
    for frame in CROWD.frames[:3]:  # the worker goes on after an error
        assert same(local.step(frame), remote.step(frame))
    processes = list(workers._processes)
    assert len(processes) == 2
    assert all(p.is_alive() for p in processes)
    remote.close()
    assert not any(p.is_alive() for p in processes)
    assert remote._workers is None
    for frame in CROWD.frames[3:6]:  # the objects go on here, exactly
        assert same(local.step(frame), remote.step(frame))
