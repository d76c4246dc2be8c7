"""engine.tracking.confidence: the calibrated confidence and the status it gives."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask
from engine.tracking.confidence import (
    COEFFICIENTS,
    EMPTY_BELOW,
    GREY_COEFFICIENTS,
    LOST_BELOW,
    SEPARATION_BELOW,
    TRACKING_FROM,
    TYPICAL_LOOK,
    UNCONFIRMED,
    Evidence,
    calibrated,
    evidence,
    shape_overlap,
    status_of,
)
from engine.tracking.maps import Maps
from engine.tracking.tracker import Tracker
from tests.engine.scenes import DiscScene
from tests.engine.tracking.moving_disc import H, R, W, centre, initial, run

U8 = NDArray[np.uint8]


def _uncapped(e: Evidence) -> float:
    """The logistic model alone, written out from :data:`COEFFICIENTS`."""
    usual_in = TYPICAL_LOOK[0] if e.usual_inside is None else e.usual_inside
    usual_out = TYPICAL_LOOK[1] if e.usual_outside is None else e.usual_outside
    inputs = [
        1.0,
        e.inside,
        e.outside,
        float(e.settled),
        e.motion_inside,
        e.motion_outside,
        float(e.motion_seen),
        max(e.shape, e.recent_shape),  # the better of the outline's and the last frames'
        e.inside - usual_in,
        e.outside - usual_out,
    ]
    return float(1.0 / (1.0 + np.exp(-np.dot(COEFFICIENTS, inputs))))


def disc_maps(origin: tuple[int, int] = (0, 0)) -> Maps:
    """p(object) 1 on a disc of radius 20 at (60, 50) of the frame, 0 elsewhere."""
    mask = contour_to_mask(circle_nodes((60.0, 50.0), 20.0, 720), (100, 120))
    ox, oy = origin
    prob = (mask[oy:, ox:] > 0).astype(np.float32)
    return Maps(origin, prob, np.zeros_like(prob))


def test_evidence_reads_inside_and_around_the_contour() -> None:
    on = evidence(disc_maps(), circle_nodes((60.0, 50.0), 20.0, 64), settled=True)
    assert on.inside == pytest.approx(1.0)
    assert on.outside < 0.05
    off = evidence(disc_maps(), circle_nodes((60.0, 50.0), 35.0, 64), settled=True)
    assert off.inside < 0.5  # the contour holds as much background as object
    assert evidence(disc_maps((7, 4)), circle_nodes((60.0, 50.0), 20.0, 64), True) == on


@pytest.mark.parametrize("centre", [(90.0, 70.0), (14.0, 70.0), (90.0, 131.0)])
def test_evidence_reads_exactly_the_pixels_of_the_whole_maps(centre: tuple[float, float]) -> None:
    """It reads only the contour's box and ring, but the very pixels (and sums) that the
    whole maps' inset and ring hold, also where the ring passes the maps' edge."""
    rng = np.random.default_rng(3)
    prob = rng.uniform(0.0, 1.0, (140, 200)).astype(np.float32)
    motion = rng.uniform(0.2, 5.0, (140, 200)).astype(np.float32)
    maps = Maps((5, 3), prob, np.zeros_like(prob), motion=motion)
    nodes = circle_nodes((centre[0] + 5, centre[1] + 3), 17.3, 48)
    found = evidence(maps, nodes, settled=True)
    mask = contour_to_mask(nodes - [5.0, 3.0], prob.shape)
    inner = cv2.erode(mask, np.ones((7, 7), np.uint8)) > 0
    ring = (cv2.dilate(mask, np.ones((21, 21), np.uint8)) > 0) & (mask == 0)
    assert found.inside == float(prob[inner].mean())
    assert found.outside == float(prob[ring].mean())
    assert found.motion_inside == float(cv2.log(motion[inner]).mean())
    assert found.motion_outside == float(cv2.log(motion[ring]).mean())


def test_evidence_outside_the_maps_is_unknown() -> None:
    far = evidence(disc_maps(), circle_nodes((900.0, 900.0), 10.0, 32), settled=False)
    assert (far.inside, far.outside) == (0.5, 0.5)


def test_confidence_rises_with_the_evidence() -> None:
    grid = np.linspace(0.0, 1.0, 11)
    for settled in (False, True):
        inside = [calibrated(Evidence(p, 0.2, settled)) for p in grid]
        outside = [calibrated(Evidence(0.8, p, settled)) for p in grid]
        shape = [calibrated(Evidence(0.8, 0.2, settled, shape=p)) for p in grid]
        # capped just under tracking: nothing object-like inside, or nothing telling the
        # inside from the ring
        model = grid >= EMPTY_BELOW
        assert np.all(np.diff(np.array(inside)[model]) > 0)
        assert np.all(np.diff(inside) >= 0)
        seen = 0.8 - grid > SEPARATION_BELOW + 1e-9
        assert np.all(np.diff(np.array(outside)[seen]) < 0)
        assert np.all(np.diff(outside) <= 0)
        assert np.all(np.diff(shape) > 0)
        assert all(0.0 < c < 1.0 for c in inside + outside)
    assert calibrated(Evidence(0.8, 0.2, True)) > calibrated(Evidence(0.8, 0.2, False))
    assert calibrated(Evidence(1.0, 0.0, True)) >= TRACKING_FROM
    nothing = calibrated(Evidence(0.5, 0.5, False))  # nothing tells object from not
    assert status_of(nothing) != "tracking"
    assert calibrated(Evidence(0.1, 0.9, False)) < LOST_BELOW  # inside out


def test_moving_with_the_object_inside_and_with_the_background_outside_raises_it() -> None:
    plain = Evidence(0.7, 0.3, True)
    agreed = Evidence(0.7, 0.3, True, motion_inside=1.5, motion_outside=-1.5, motion_seen=True)
    crossed = Evidence(0.7, 0.3, True, motion_inside=-1.5, motion_outside=1.5, motion_seen=True)
    assert calibrated(agreed) > calibrated(crossed)
    assert calibrated(agreed) > calibrated(plain)


def test_evidence_reads_the_motion_contrast_where_it_was_measured() -> None:
    maps = disc_maps()
    inside = maps.probability > 0
    motion = np.where(inside, np.float32(np.e), np.float32(1 / np.e)).astype(np.float32)
    moved = evidence(
        Maps(maps.origin, maps.probability, maps.edges, motion=motion),
        circle_nodes((60.0, 50.0), 20.0, 64),
        settled=True,
    )
    assert moved.motion_seen
    assert moved.motion_inside == pytest.approx(1.0, abs=1e-5)
    assert moved.motion_outside < -0.9
    still = evidence(maps, circle_nodes((60.0, 50.0), 20.0, 64), settled=True)
    assert not still.motion_seen
    assert still.motion_inside == still.motion_outside == 0.0


def test_shape_overlap_ignores_place_and_size() -> None:
    disc = circle_nodes((60.0, 50.0), 20.0, 64)
    assert shape_overlap(disc, disc) == pytest.approx(1.0)
    flat = disc * [1.0, 0.6]
    for scale, shift in [(3.0, (400.0, -90.0)), (0.2, (-7.5, 3.25)), (11.0, (0.0, 0.0))]:
        assert shape_overlap(flat, scale * flat + shift) == pytest.approx(1.0)
    assert shape_overlap(disc, disc[::-1]) > 0.97  # either winding


@pytest.mark.parametrize(
    "bad", [[[0.0, 0.0], [1.0, 1.0]], [[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]], [1.0, 2.0, 3.0]]
)
def test_shape_overlap_rejects_what_is_not_a_contour(bad: object) -> None:
    disc = circle_nodes((0.0, 0.0), 20.0, 64)
    with pytest.raises(ValueError, match="nodes"):
        shape_overlap(np.asarray(bad), disc)
    with pytest.raises(ValueError, match="nodes"):
        shape_overlap(disc, np.asarray(bad))


def test_shape_overlap_falls_as_the_shape_departs() -> None:
    disc = circle_nodes((0.0, 0.0), 20.0, 64)
    ellipses = [disc * [1.0, k] for k in (1.0, 0.8, 0.5, 0.25)]
    overlaps = [shape_overlap(e, disc) for e in ellipses]
    assert np.all(np.diff(overlaps) < 0)
    assert overlaps[-1] < 0.6
    # rotation is kept: the outline turns with the object
    lying, standing = disc * [1.0, 0.25], disc * [0.25, 1.0]
    assert shape_overlap(lying, standing) < 0.3
    # no area: nothing like any shape
    line = np.column_stack([np.linspace(0.0, 10.0, 8), np.zeros(8)])
    assert shape_overlap(line, disc) == shape_overlap(disc, line) == 0.0


def test_evidence_judges_the_shape_against_the_outline_given() -> None:
    nodes = circle_nodes((60.0, 50.0), 20.0, 64)
    assert evidence(disc_maps(), nodes, True).shape == 1.0  # no outline: not judged
    same = evidence(disc_maps(), nodes, True, outline=0.5 * nodes)
    assert same.shape > 0.97
    flat = evidence(disc_maps(), nodes, True, outline=nodes * [1.0, 0.2])
    assert flat.shape < 0.5
    assert calibrated(flat) < calibrated(same)
    assert (flat.inside, flat.outside) == (same.inside, same.outside)


@pytest.mark.parametrize(
    ("confidence", "status"),
    [
        (1.0, "tracking"),
        (TRACKING_FROM, "tracking"),
        (np.nextafter(TRACKING_FROM, 0.0), "uncertain"),
        (LOST_BELOW, "uncertain"),
        (np.nextafter(LOST_BELOW, 0.0), "lost"),
        (0.0, "lost"),
    ],
)
def test_status_thresholds(confidence: float, status: str) -> None:
    assert status_of(float(confidence)) == status


def test_a_followed_object_is_tracking_and_a_vanished_one_is_not(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    results = run(tracker, frames[:8])
    assert [r.status for r in results] == ["tracking"] * 8
    assert min(r.confidence for r in results) >= 0.8
    # the disc leaves: the same textured background without it
    empty = DiscScene(W, H, R, seed=11).frame((-10 * R, -10 * R))
    after = run(tracker, [empty] * 3)
    assert all(r.status != "tracking" for r in after), [r.confidence for r in after]


def test_the_tracker_shows_the_evidence_behind_its_confidence(frames: list[U8]) -> None:
    tracker = Tracker(initial())
    assert tracker.evidence is None
    tracker.step(frames[0])
    assert tracker.evidence is None  # a first frame is taken as given, not judged
    for frame in frames[1:6]:
        result = tracker.step(frame)
        assert tracker.evidence is not None
        assert result.confidence == calibrated(tracker.evidence)
    last = tracker.evidence
    assert last is not None
    assert last.inside > 0.8 > 0.2 > last.outside
    assert last.shape > 0.9  # the disc keeps the first frame's shape
    assert Tracker.from_state(tracker.to_state()).evidence is None  # not a state
    tracker.step(np.zeros((2, 2, 3), np.uint8))  # nothing to track in so small a frame
    assert tracker.evidence is None


def test_grey_evidence_is_read_with_the_grey_model() -> None:
    def logistic(model: tuple[float, ...], e: Evidence) -> float:
        features = [e.inside, e.outside, float(e.settled), e.motion_inside, e.motion_outside]
        features += [float(e.motion_seen), e.shape, *e.change]
        return float(1.0 / (1.0 + np.exp(-(model[0] + np.dot(model[1:], features)))))

    e = Evidence(0.7, 0.25, True, 0.5, -0.5, True, 0.8, usual_inside=0.75, usual_outside=0.2)
    grey = Evidence(0.7, 0.25, True, 0.5, -0.5, True, 0.8, 0.75, 0.2, grey=True)
    assert calibrated(e) == pytest.approx(logistic(COEFFICIENTS, e))
    assert calibrated(grey) == pytest.approx(logistic(GREY_COEFFICIENTS, grey))
    assert calibrated(grey) != pytest.approx(calibrated(e), abs=1e-3)
    # the same caps, and the same direction in every input that matters
    assert calibrated(Evidence(0.3, 0.1, True, grey=True)) <= UNCONFIRMED
    assert calibrated(Evidence(0.6, 0.55, True, grey=True)) <= UNCONFIRMED
    grid = np.linspace(0.4, 1.0, 7)
    inside = [calibrated(Evidence(p, 0.1, True, grey=True)) for p in grid]
    shape = [calibrated(Evidence(0.8, 0.2, True, shape=p, grey=True)) for p in grid]
    assert np.all(np.diff(inside) > 0)
    assert np.all(np.diff(shape) > 0)
    assert status_of(calibrated(Evidence(0.95, 0.05, True, grey=True))) == "tracking"


def test_the_tracker_reads_a_grey_frames_evidence_with_the_grey_model(
    frames: list[U8],
) -> None:
    grey = [np.asarray(cv2.cvtColor(f, cv2.COLOR_BGR2GRAY), np.uint8) for f in frames[:4]]
    for texture in (True, False):
        tracker = Tracker(initial(), grey_texture=texture)
        for frame in grey:
            result = tracker.step(frame)
        assert tracker.evidence is not None
        assert tracker.evidence.grey is texture  # without texture, colour models read it
        assert result.confidence == calibrated(tracker.evidence)
    colour = Tracker(initial())
    run(colour, frames[:4])
    assert colour.evidence is not None
    assert not colour.evidence.grey


def test_the_ring_is_read_against_how_it_usually_looks() -> None:
    """A ring as object-like as a banner of the rider's colours, round a contour half of
    the first frame's shape and fairly like its last frames' (0.75): lost when the ring was
    clear at the start, the object among its own colours when it always looked so.  (Since
    the recent shapes the model weighs the usual look less and the shape more: the ring's
    change decides in a narrower band of shapes.)"""
    slid = Evidence(
        0.85, 0.47, False, shape=0.5, usual_inside=0.85, usual_outside=0.2, recent_shape=0.75
    )
    always = Evidence(
        0.85, 0.47, False, shape=0.5, usual_inside=0.85, usual_outside=0.47, recent_shape=0.75
    )
    assert calibrated(slid) < TRACKING_FROM <= calibrated(always)
    assert calibrated(slid) == pytest.approx(_uncapped(slid))
    # not known: the thirty's typical look
    typical = Evidence(
        0.85, 0.47, False, usual_inside=TYPICAL_LOOK[0], usual_outside=TYPICAL_LOOK[1]
    )
    assert calibrated(Evidence(0.85, 0.47, False)) == calibrated(typical)


def test_the_usual_look_is_learnt_from_the_first_frames_of_a_track() -> None:
    from engine.tracking.confidence import USUAL_FRAMES

    scene = DiscScene(W, H, R)
    tracker = Tracker(initial())
    frames = [scene.frame(centre(k)) for k in range(USUAL_FRAMES + 4)]
    seen = []
    for frame in frames:
        tracker.step(frame)
        if tracker.evidence is not None:
            seen.append((tracker.evidence.inside, tracker.evidence.outside))
            usual_in, usual_out = tracker.evidence.usual_inside, tracker.evidence.usual_outside
            assert usual_in is not None
            assert usual_out is not None
            count = min(len(seen), USUAL_FRAMES)
            mean = np.mean(seen[:count], axis=0)
            np.testing.assert_allclose([usual_in, usual_out], mean, rtol=1e-12)
    assert len(seen) > USUAL_FRAMES


def test_a_contour_with_nothing_object_like_inside_is_not_tracking() -> None:
    # left on an occluder that hides the whole object: nothing around it either
    empty = Evidence(inside=0.05, outside=0.0, settled=True)
    assert calibrated(empty) <= UNCONFIRMED < TRACKING_FROM
    assert status_of(calibrated(empty)) == "uncertain"
    # a dim inside the linear model alone would call tracking: the cap holds it below
    dim = Evidence(inside=EMPTY_BELOW - 0.05, outside=0.0, settled=True)
    assert _uncapped(dim) > TRACKING_FROM
    assert calibrated(dim) == UNCONFIRMED
    assert calibrated(Evidence(inside=EMPTY_BELOW, outside=0.0, settled=True)) > TRACKING_FROM
    # below the cap the model's own value stands: background inside, the object all round
    lost = Evidence(inside=0.05, outside=0.9, settled=False)
    assert calibrated(lost) < LOST_BELOW


def test_a_contour_that_nothing_tells_from_its_surroundings_is_not_tracking() -> None:
    # no colour known (a black frame): the chain kept the shape, but nothing else is seen
    unknown = Evidence(inside=0.5, outside=0.5, settled=True, shape=1.0)
    assert calibrated(unknown) <= UNCONFIRMED
    # barely more object-like inside than out: the linear model alone would call it tracking
    faint = Evidence(inside=0.55, outside=0.5, settled=True, shape=1.0)
    assert _uncapped(faint) > TRACKING_FROM
    assert calibrated(faint) == UNCONFIRMED
    edge = 0.3 + SEPARATION_BELOW
    assert calibrated(Evidence(inside=edge - 0.01, outside=0.3, settled=True)) == UNCONFIRMED
    assert calibrated(Evidence(inside=edge + 0.01, outside=0.3, settled=True)) > TRACKING_FROM


def test_a_wholly_hidden_object_is_never_reported_tracking() -> None:
    from engine.geometry import mask_to_contour
    from engine.testing.synthetic import make_sequence

    # seed 21: the contour stays on the hider, settled, with nothing object-like around
    seq = make_sequence("hidden", seed=21, length=40)
    tracker = Tracker(mask_to_contour(seq.masks[0], 128))
    hidden = []
    for frame, visible in zip(seq.frames, seq.visible, strict=True):
        result = tracker.step(frame)
        if not visible:
            hidden.append(result.status)
    assert hidden
    assert "tracking" not in hidden, hidden
