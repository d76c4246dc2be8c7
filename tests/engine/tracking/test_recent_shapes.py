"""engine.tracking.recent_shapes: a contour's shape judged against the last frames on the object."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.geometry import circle_nodes
from engine.tracking._shape_kernels import best_overlap
from engine.tracking._state_codec import pack_raw
from engine.tracking.confidence import (
    Evidence,
    calibrated,
    evidence,
    shape_mask,
    shape_overlap,
)
from engine.tracking.maps import Maps
from engine.tracking.memory import Memory
from engine.tracking.recent_shapes import RECENT_FRAMES, RecentShapes, remembered

DISC = circle_nodes((60.0, 50.0), 20.0, 64)


def stretched(k: float) -> np.ndarray:
    """The disc stretched k times along x about its centre."""
    return (DISC - [60.0, 50.0]) * [k, 1.0] + [60.0, 50.0]


def overlap(recent: RecentShapes, nodes: np.ndarray) -> float:
    """The best overlap of the contour ``nodes``' shape with the recent shapes."""
    return recent.overlap(shape_mask(nodes))


def disc_maps() -> Maps:
    """p(object) 0.9 on a wide ellipse around the disc (room for every stretch), 0.1 elsewhere."""
    ys, xs = np.mgrid[0:100, 0:120]
    inside = ((xs - 60.0) / 45.0) ** 2 + ((ys - 50.0) / 25.0) ** 2 <= 1.0
    p = np.where(inside, 0.9, 0.1).astype(np.float32)
    return Maps((0, 0), p, np.zeros_like(p))


def test_a_shape_that_changed_gradually_matches_the_frames_before_it() -> None:
    recent = RecentShapes()
    for k in np.linspace(1.0, 1.9, 10):  # a dog stretching out as it runs
        recent.add(stretched(float(k)), True)
    now = stretched(2.0)
    assert shape_overlap(now, DISC) < 0.75  # far from the first frame's outline
    assert overlap(recent, now) > 0.95  # close to the last frame's
    # the place and the size do not count, as with the outline
    assert overlap(recent, 0.5 * now + 7.0) == pytest.approx(overlap(recent, now), abs=0.02)


def test_only_the_last_frames_on_the_object_count() -> None:
    recent = RecentShapes()
    assert overlap(recent, DISC) == 0.0  # none known
    recent.add(DISC, True)
    assert overlap(recent, DISC) == 1.0
    recent.add(stretched(3.0), False)  # not on the object: not kept
    assert overlap(recent, stretched(3.0)) == pytest.approx(shape_overlap(stretched(3.0), DISC))
    for _ in range(RECENT_FRAMES - 1):
        recent.add(stretched(3.0), False)
    assert overlap(recent, DISC) == 0.0  # the disc is RECENT_FRAMES frames back: forgotten


def test_evidence_reads_the_better_of_the_outline_and_the_recent_shapes() -> None:
    recent = RecentShapes()
    for k in np.linspace(1.0, 1.9, 10):
        recent.add(stretched(float(k)), True)
    now = stretched(2.0)
    alone = evidence(disc_maps(), now, True, outline=DISC)
    both = evidence(disc_maps(), now, True, outline=DISC, recent=recent)
    assert both.shape == alone.shape < 0.75  # the outline's overlap, as it was
    assert both.recent_shape > 0.95
    assert both.judged_shape == both.recent_shape
    assert calibrated(both) > calibrated(alone)
    # the gate reads the outline alone: the recent shapes cannot vouch for themselves
    assert remembered(both) == remembered(alone)
    # no outline (no shape memory): the shape is not judged at all
    assert evidence(disc_maps(), now, True, recent=recent).judged_shape == 1.0


def test_the_judged_shape_is_the_one_remembered() -> None:
    """The evidence keeps the contour's shape it judged; given to ``add``, that shape is
    kept as ``add`` would have made it, and a frame not remembered keeps none."""
    now = stretched(1.4)
    judged = evidence(disc_maps(), now, True, outline=DISC).silhouette
    assert judged is not None
    np.testing.assert_array_equal(judged, shape_mask(now))
    assert evidence(disc_maps(), now, True).silhouette is None  # the shape not judged
    given_shape, made = RecentShapes(), RecentShapes()
    given_shape.add(now, True, judged)
    made.add(now, True)
    given_shape.add(now, False, judged)
    made.add(now, False)
    assert given_shape.to_state() == made.to_state()


def test_the_gate_is_the_outline_models_threshold() -> None:
    # an object-like inside, its ring a little object-like too (a banner of its colours)
    good = Evidence(0.85, 0.3, True, shape=0.95)
    slid = Evidence(0.85, 0.3, True, shape=0.2, recent_shape=0.95)  # vouched for by itself
    assert remembered(good)
    assert calibrated(slid) == pytest.approx(calibrated(good))  # reported as alike...
    assert not remembered(slid)  # ...but its shape is not remembered


def test_the_recent_shapes_survive_the_state_bit_for_bit() -> None:
    memory = Memory.fresh(DISC)
    for k, on in ((1.0, True), (1.3, False), (1.6, True)):
        memory.recent.add(stretched(k), on)
    state = json.loads(json.dumps(memory.to_state()))
    assert [s is None for s in state["recent"]] == [False, True, False]
    back = Memory.from_state(state, len(DISC))
    for k in (1.0, 1.8, 2.5):
        assert overlap(back.recent, stretched(k)) == overlap(memory.recent, stretched(k))
    older = {key: v for key, v in state.items() if key != "recent"}  # written before them
    assert overlap(Memory.from_state(older, len(DISC)).recent, DISC) == 0.0


@pytest.mark.parametrize(
    "bad",
    [
        "shapes",
        [None] * (RECENT_FRAMES + 1),
        [3],
        ["not base64 at all"],
        [pack_raw(np.packbits(np.zeros((8, 8), bool)))],  # the wrong size
    ],
)
def test_malformed_recent_shapes_are_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="recent shape"):
        RecentShapes.from_state(bad)


def test_a_shape_of_the_wrong_size_is_refused() -> None:
    with pytest.raises(ValueError, match="recent shape must be"):
        RecentShapes([np.zeros((8, 8), bool)])


@settings(max_examples=30, deadline=None)
@given(st.integers(1, RECENT_FRAMES), st.integers(0, 2**32 - 1), st.floats(0.0, 1.0))
def test_the_best_overlap_is_numpys_count(kept: int, seed: int, fill: float) -> None:
    """The compiled count gives numpy's IoUs' maximum bit for bit, empty grids included."""
    rng = np.random.default_rng(seed)
    stack = rng.uniform(size=(kept, 24, 24)) < fill * rng.uniform(size=(kept, 1, 1))
    shape = rng.uniform(size=(24, 24)) < fill
    union = np.count_nonzero(stack | shape, axis=(1, 2))
    common = np.count_nonzero(stack & shape, axis=(1, 2))
    flags = rng.uniform(size=kept) < 0.7
    flags[rng.integers(kept)] = True  # at least one kept
    iou = common / np.maximum(union, 1)
    assert best_overlap(stack, flags, shape) == float(np.max(iou[flags]))


def test_the_ring_holds_the_last_frames_in_any_order_of_slots() -> None:
    """More frames than the ring has slots: the comparison reads the same shapes as the
    list kept for the state, whatever slot each landed in, and so does a restored copy."""
    recent = RecentShapes()
    for k in range(2 * RECENT_FRAMES + 3):  # wrapped round twice, every third not kept
        recent.add(stretched(1.0 + 0.05 * k), k % 3 != 0)
    restored = RecentShapes.from_state(json.loads(json.dumps(recent.to_state())))
    kept = [
        shape_mask(stretched(1.0 + 0.05 * k))
        for k in range(RECENT_FRAMES + 3, 2 * RECENT_FRAMES + 3)
        if k % 3
    ]
    for probe in (stretched(1.2), stretched(2.5), stretched(3.0)):
        mine = shape_mask(probe)
        assert mine is not None
        expected = max(
            int(np.count_nonzero(s & mine)) / max(int(np.count_nonzero(s | mine)), 1)
            for s in kept
            if s is not None
        )
        assert recent.overlap(mine) == restored.overlap(mine) == expected
