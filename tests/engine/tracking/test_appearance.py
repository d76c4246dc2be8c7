"""engine.tracking.appearance: the object-versus-background colour model."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes
from engine.tracking._state_codec import pack_histogram
from engine.tracking.appearance import (
    COLOUR_BITS,
    LEGACY_COLOUR_BITS,
    ColourHistogram,
    Histograms,
    quantise,
)
from tests.engine.scenes import disc_mask, two_colour_frame

U8 = NDArray[np.uint8]

CENTER, RADIUS, BAND = (80.0, 60.0), 25.0, 15
NODES = circle_nodes(CENTER, RADIUS, 64)
SHAPE = (120, 160)


def regions() -> tuple[NDArray[np.bool_], NDArray[np.bool_], NDArray[np.bool_]]:
    """Pixels inside the disc, outside it, and in the band the model learnt from.

    All at least 2 px from the disc's edge.
    """
    inner = disc_mask(CENTER, RADIUS - 2, SHAPE) > 0
    outer = disc_mask(CENTER, RADIUS + 2, SHAPE) == 0
    band = outer & (disc_mask(CENTER, RADIUS + BAND, SHAPE) > 0)
    return inner, outer, band


def grey(frame: U8) -> U8:
    return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)


@pytest.mark.parametrize("as_grey", [False, True], ids=["bgr", "grey"])
def test_probability_separates_a_two_colour_scene(as_grey: bool) -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    if as_grey:
        frame = grey(frame)
    model = Histograms.fit(frame, NODES, BAND)
    prob = model.probability(frame)
    assert prob.shape == SHAPE
    assert prob.dtype == np.float32
    assert ((prob >= 0) & (prob <= 1)).all()
    inner, outer, band = regions()
    # at 32 levels a rare noise colour inside may be one the fit never saw: neutral 0.5
    assert prob[inner].min() >= (0.8 if as_grey else 0.5)
    assert (prob[inner] > 0.8).mean() > 0.99
    assert prob[band].max() < 0.2
    # far away, a noise colour never seen in the band may get the neutral 0.5
    assert (prob[outer] < 0.2).mean() > 0.99
    assert model.separation() > 0.8


def test_histograms_are_normalised_and_sized_by_frame_kind() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    colour = Histograms.fit(frame, NODES, BAND)
    mono = Histograms.fit(grey(frame), NODES, BAND)
    assert colour.object_hist.shape == colour.background_hist.shape
    assert mono.object_hist.shape == mono.background_hist.shape
    assert len(mono.object_hist) < len(colour.object_hist)
    for hist in (colour.object_hist, colour.background_hist, mono.object_hist):
        assert hist.sum() == pytest.approx(1.0)
        assert (hist >= 0).all()


def test_probability_of_a_sub_image_matches_the_whole_frame() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = Histograms.fit(frame, NODES, BAND)
    whole = model.probability(frame)
    np.testing.assert_array_equal(model.probability(frame[30:90, 40:120]), whole[30:90, 40:120])


def test_probability_of_the_other_frame_kind_is_uninformative() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = Histograms.fit(frame, NODES, BAND)
    np.testing.assert_array_equal(model.probability(grey(frame)), np.full(SHAPE, 0.5, np.float32))


def test_separation_high_for_distinct_colours_and_zero_for_identical() -> None:
    distinct = Histograms.fit(two_colour_frame(CENTER, RADIUS, SHAPE), NODES, BAND)
    assert distinct.separation() > 0.9
    flat = np.full((*SHAPE, 3), (90, 120, 150), np.uint8)
    same = Histograms.fit(flat, NODES, BAND)
    assert same.separation() == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(same.probability(flat), 0.5, atol=1e-3)
    noisy = two_colour_frame(
        CENTER, RADIUS, SHAPE, inside_bgr=(120, 120, 120), outside_bgr=(120, 120, 120), noise=20
    )
    similar = Histograms.fit(noisy, NODES, BAND)
    assert similar.separation() < 0.3


def bins_of(frame: U8, where: NDArray[np.bool_]) -> NDArray[np.intp]:
    """The histogram bins of the pixels of ``frame`` at ``where``."""
    return np.unique(quantise(frame)[where])


def test_updated_with_rate_zero_keeps_the_model_which_is_immutable() -> None:
    first = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = Histograms.fit(first, NODES, BAND)
    snapshot = (model.object_hist.copy(), model.background_hist.copy())
    kept = model.updated(two_colour_frame(CENTER, RADIUS, SHAPE, seed=1), NODES, BAND, 0.0)
    np.testing.assert_array_equal(kept.object_hist, snapshot[0])
    np.testing.assert_array_equal(kept.background_hist, snapshot[1])
    model.updated(two_colour_frame(CENTER, RADIUS, SHAPE, seed=2), NODES, BAND, 0.5)
    np.testing.assert_array_equal(model.object_hist, snapshot[0])
    np.testing.assert_array_equal(model.background_hist, snapshot[1])


def test_updated_blends_in_a_frame_that_agrees_with_the_model() -> None:
    """Same scene, new noise: the blend is (1 - rate) old + rate new, new ~ a fresh fit."""
    rate = 0.25
    model = Histograms.fit(two_colour_frame(CENTER, RADIUS, SHAPE), NODES, BAND)
    second = two_colour_frame(CENTER, RADIUS, SHAPE, seed=1)
    blended = model.updated(second, NODES, BAND, rate)
    fresh = Histograms.fit(second, NODES, BAND)
    pairs = [
        (blended.object_hist, model.object_hist, fresh.object_hist),
        (blended.background_hist, model.background_hist, fresh.background_hist),
    ]
    for mixed, old, fit in pairs:
        learnt = (mixed - (1 - rate) * old) / rate
        assert learnt.min() >= -1e-12
        assert learnt.sum() == pytest.approx(1.0)
        assert np.abs(learnt - fit).sum() < 0.1  # nearly all of the frame was learnt
        assert mixed.sum() == pytest.approx(1.0)


def test_updated_learns_new_background_colours_but_not_into_the_object() -> None:
    model = Histograms.fit(two_colour_frame(CENTER, RADIUS, SHAPE), NODES, BAND)
    teal = two_colour_frame(CENTER, RADIUS, SHAPE, outside_bgr=(200, 200, 30), seed=1)
    lagging = circle_nodes((CENTER[0] + 8, CENTER[1]), RADIUS, 64)  # 8 px off: covers teal
    blended = model.updated(teal, lagging, BAND, 0.25)
    _, outer, _ = regions()
    new = bins_of(teal, outer)
    assert blended.background_hist[new].sum() > 0.2
    assert blended.object_hist[new].sum() < 1e-3
    # while a fresh fit on the lagging contour would take teal for the object
    assert Histograms.fit(teal, lagging, BAND).object_hist[new].sum() > 0.05


def test_updated_keeps_histograms_normalised() -> None:
    """Histograms sum to 1 even when no pixel of the new frame passes the agreement test."""
    model = Histograms.fit(two_colour_frame(CENTER, RADIUS, SHAPE), NODES, BAND)
    green = two_colour_frame(CENTER, RADIUS, SHAPE, inside_bgr=(40, 200, 40), seed=1)
    blended = model.updated(green, NODES, BAND, 0.25)
    assert blended.object_hist.sum() == pytest.approx(1.0)
    assert blended.background_hist.sum() == pytest.approx(1.0)
    inner, _, _ = regions()
    prob = blended.probability(two_colour_frame(CENTER, RADIUS, SHAPE, seed=2))
    # the red object is still the object (but for rare noise colours, at 32 levels)
    assert (prob[inner] > 0.8).mean() > 0.98


def test_updated_with_the_other_frame_kind_starts_afresh() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = Histograms.fit(frame, NODES, BAND)
    switched = model.updated(grey(frame), NODES, BAND, 0.1)
    np.testing.assert_array_equal(
        switched.object_hist, Histograms.fit(grey(frame), NODES, BAND).object_hist
    )


def test_contour_outside_the_frame_gives_an_empty_uninformative_model() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = Histograms.fit(frame, circle_nodes((-200.0, -200.0), 10.0, 16), BAND)
    assert not model.object_hist.any()
    assert not model.background_hist.any()
    prob = model.probability(frame)
    assert np.isfinite(prob).all()
    np.testing.assert_allclose(prob, 0.5)


def _scene_with_a_far_patch() -> tuple[U8, NDArray[np.bool_]]:
    """The two-colour scene with a blue patch in a corner, beyond two rings of the disc."""
    frame = two_colour_frame(CENTER, RADIUS, SHAPE).copy()
    patch = np.zeros(SHAPE, bool)
    patch[:15, 135:] = True
    frame[patch] = (200, 40, 40)  # BGR blue: in neither the disc nor its ring
    return frame, patch


def test_far_background_knows_the_colours_the_ring_does_not_show() -> None:
    frame, patch = _scene_with_a_far_patch()
    ring_only = Histograms.fit(frame, NODES, BAND)
    with_far = Histograms.fit(frame, NODES, BAND, far=0.2)
    # the ring never saw the patch: unknown (0.5) to it, background with the far share
    assert ring_only.probability(frame)[patch].min() == pytest.approx(0.5)
    assert with_far.probability(frame)[patch].max() < 0.01
    # the object and its ring read as before
    inner, _, band = regions()
    assert (with_far.probability(frame)[inner] > 0.8).mean() > 0.99
    assert with_far.probability(frame)[band].max() < 0.2
    np.testing.assert_array_equal(with_far.object_hist, ring_only.object_hist)
    assert with_far.background_hist.sum() == pytest.approx(1.0)
    # the limits: 0 is the ring alone, 1 the far pixels alone
    np.testing.assert_array_equal(
        Histograms.fit(frame, NODES, BAND, far=0.0).background_hist, ring_only.background_hist
    )
    far_only = Histograms.fit(frame, NODES, BAND, far=1.0).background_hist
    blue = quantise(frame)[patch][0]
    assert far_only[blue] > patch.sum() / patch.size  # a share of the far pixels, not the frame
    assert far_only[quantise(frame)[inner][0]] == 0  # nothing of the object's


def test_far_background_needs_pixels_beyond_two_rings() -> None:
    frame, _ = _scene_with_a_far_patch()
    big = circle_nodes(CENTER, 200.0, 64)  # the whole frame within reach
    np.testing.assert_array_equal(
        Histograms.fit(frame, big, BAND, far=0.5).background_hist,
        Histograms.fit(frame, big, BAND).background_hist,
    )


# the synthetic "matched_background": the object's colour, 8 levels bluer and 3 less red
OBJECT_BGR, MATCHED_BGR = (55, 60, 150), (63, 60, 147)


def test_32_levels_tell_apart_a_colour_8_levels_off_which_16_levels_merge() -> None:
    frame = two_colour_frame(
        CENTER, RADIUS, SHAPE, inside_bgr=OBJECT_BGR, outside_bgr=MATCHED_BGR, noise=0.0
    )
    inner, _, band = regions()
    fine = Histograms.fit(frame, NODES, BAND).probability(frame)
    assert COLOUR_BITS == 5
    assert fine[inner].min() > 0.9
    assert fine[band].max() < 0.1
    coarse = Histograms.fit(frame, NODES, BAND, colour_bits=4).probability(frame)
    assert coarse[inner].min() == coarse[band].max()  # one bin: no telling them apart


@pytest.mark.parametrize("bits", [0, 6, 4.0, True, "5", None], ids=repr)
def test_colour_histogram_refuses_bits_it_cannot_bin(bits: object) -> None:
    with pytest.raises(ValueError, match="colour_bits"):
        ColourHistogram(BAND, 0.1, 0.0, bits)  # type: ignore[arg-type]


@pytest.mark.parametrize("bits", [LEGACY_COLOUR_BITS, COLOUR_BITS])
def test_a_state_resumes_at_its_colour_levels(bits: int) -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = ColourHistogram(BAND, 0.1, 0.0, bits)
    model.fit(frame, NODES)
    restored = ColourHistogram(BAND, 0.1, 0.0, bits).from_state(model.to_state())
    assert restored.colour_bits == bits
    np.testing.assert_array_equal(restored.probability(frame), model.probability(frame))
    second = two_colour_frame(CENTER, RADIUS, SHAPE, seed=3)
    model.update(second, NODES)
    restored.update(second, NODES)
    np.testing.assert_array_equal(restored.probability(frame), model.probability(frame))


def test_a_state_of_other_colour_levels_is_refused_but_grey_ones_fit_any() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = ColourHistogram(BAND, 0.1, 0.0, LEGACY_COLOUR_BITS)
    model.fit(frame, NODES)
    with pytest.raises(ValueError, match="colour_bits=5"):
        ColourHistogram(BAND, 0.1).from_state(model.to_state())
    model.fit(grey(frame), NODES)
    restored = ColourHistogram(BAND, 0.1).from_state(model.to_state())
    np.testing.assert_array_equal(restored.probability(grey(frame)), model.probability(grey(frame)))


@pytest.mark.parametrize(
    "state",
    [
        {"kind": "colour-histogram", "object": None, "background": pack_histogram(np.ones(32))},
        {"kind": "colour-histogram", "object": pack_histogram(np.ones(32)), "background": 7},
    ],
    ids=["one missing", "not text"],
)
def test_a_state_with_one_histogram_is_refused(state: dict[str, object]) -> None:
    with pytest.raises(ValueError, match="both histograms"):
        ColourHistogram(BAND, 0.1).from_state(state)


def test_an_empty_state_keeps_the_models_levels() -> None:
    empty = {"kind": "colour-histogram", "object": None, "background": None}
    restored = ColourHistogram(BAND, 0.1, 0.0, LEGACY_COLOUR_BITS).from_state(empty)
    assert restored.colour_bits == LEGACY_COLOUR_BITS
    assert restored.histograms is None


def test_a_compact_state_keeps_the_histograms_to_three_digits() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    model = ColourHistogram(BAND, 0.1)
    model.fit(frame, NODES)
    compact = model.to_compact_state()
    assert compact["dtype"] == "float16"
    assert len(str(compact["background"])) < len(str(model.to_state()["background"]))
    restored = ColourHistogram(BAND, 0.1).from_state(compact)
    assert restored.histograms is not None
    assert model.histograms is not None
    np.testing.assert_allclose(
        restored.histograms.object_hist, model.histograms.object_hist, rtol=1e-3, atol=1e-7
    )
    np.testing.assert_allclose(restored.probability(frame), model.probability(frame), atol=2e-3)
    empty = ColourHistogram(BAND, 0.1).to_compact_state()
    assert ColourHistogram(BAND, 0.1).from_state(empty).histograms is None
