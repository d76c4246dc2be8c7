"""engine.tracking.BandCut and LocalColour: the joint band segmentation after the chain."""

from __future__ import annotations

import itertools
import math

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou, resample
from engine.tracking import BandCut, Maps, Tracker, segmentation
from engine.tracking._cut_kernels import PROBABILITY_FLOOR, SHAPE_CLIP
from engine.tracking.appearance import quantise
from engine.tracking.local_colour import LocalColour
from engine.tracking.segmentation import (
    COLOUR_WEIGHT,
    FINE_INSIDE,
    FINE_OUTSIDE,
    SHAPE_SCALE,
    SHAPE_WEIGHT,
    SMOOTHNESS,
    _cut,
    _full_resolution,
    _scale,
    _signed_distance,
)

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]


def energy(
    labels: NDArray[np.bool_],
    distance: NDArray[np.float32],
    band: float,
    image: U8,
    probability: NDArray[np.float32],
) -> float:
    """E(L) of the segmentation module's docstring, written out pixel by pixel."""
    h, w = distance.shape
    free = np.abs(distance) <= band
    total = 0.0
    diffs = []
    for y, x in zip(*np.nonzero(free), strict=True):
        for dy, dx in ((0, 1), (1, 0)):
            if y + dy < h and x + dx < w:
                d = image[y, x].astype(float) - image[y + dy, x + dx].astype(float)
                diffs.append(float(d @ d))
    contrast = 1.0 / (2.0 * max(float(np.mean(diffs)), 1e-6))
    for y, x in zip(*np.nonzero(free), strict=True):
        p = min(max(float(probability[y, x]), PROBABILITY_FLOOR), 1 - PROBABILITY_FLOOR)
        shape = min(max(float(distance[y, x]) / SHAPE_SCALE, -SHAPE_CLIP), SHAPE_CLIP)
        u = COLOUR_WEIGHT * math.log(p / (1 - p)) + SHAPE_WEIGHT * shape
        total += max(-u, 0.0) if labels[y, x] else max(u, 0.0)
    for y in range(h):
        for x in range(w):
            for dy, dx in ((0, 1), (1, 0)):
                yy, xx = y + dy, x + dx
                if yy >= h or xx >= w or not (free[y, x] or free[yy, xx]):
                    continue
                if labels[y, x] != labels[yy, xx]:
                    d = image[y, x].astype(float) - image[yy, xx].astype(float)
                    total += SMOOTHNESS * math.exp(-contrast * float(d @ d))
    return total


@pytest.mark.parametrize("seed", range(6))
def test_the_cut_is_the_minimum_energy_labelling(seed: int) -> None:
    """Against every labelling of the band's pixels, enumerated."""
    rng = np.random.default_rng(seed)
    h, w = 5, 6
    inside = np.zeros((h, w), np.uint8)
    inside[1:3, 2:4] = 1
    distance = _signed_distance(inside)
    band = 1.0
    free = np.abs(distance) <= band
    assert 8 <= free.sum() <= 16  # small enough to enumerate
    image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    probability = rng.uniform(0.0, 1.0, (h, w)).astype(np.float32)
    found = _cut(distance, band, image, probability, 1)
    np.testing.assert_array_equal(found[~free], distance[~free] > band)
    best = math.inf
    spots = list(zip(*np.nonzero(free), strict=True))
    for bits in itertools.product((False, True), repeat=len(spots)):
        labels = distance > band
        for (y, x), bit in zip(spots, bits, strict=True):
            labels[y, x] = bit
        best = min(best, energy(labels, distance, band, image, probability))
    assert energy(found, distance, band, image, probability) == pytest.approx(best, abs=1e-9)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), sure=st.floats(0.0, 1.0))
def test_settling_keeps_the_minimum_cut(seed: int, sure: float) -> None:
    """The settled cut's energy is the plain maximum flow's, on random bands.

    ``sure`` pulls p(object) towards 0 or 1, from bands where nothing settles to bands
    where nearly everything does.
    """
    import maxflow

    from engine.tracking._cut_kernels import band_graph, settle

    rng = np.random.default_rng(seed)
    h, w = 14, 16
    inside = np.zeros((h, w), np.uint8)
    inside[3:11, 4:12] = 1
    distance = _signed_distance(inside)
    band = 2.0
    image = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
    noise = rng.uniform(0.0, 1.0, (h, w))
    probability = np.clip(0.5 + (noise - 0.5) * (1 + 20 * sure), 0, 1).astype(np.float32)
    found = _cut(distance, band, image, probability, 1)
    # the plain flow on the whole band, without the settling
    weights = np.array([COLOUR_WEIGHT, SHAPE_WEIGHT, SMOOTHNESS, SHAPE_SCALE])
    pixels, source, sink, neighbours, capacities = band_graph(
        distance, band, image, probability, weights
    )
    everything = settle(np.zeros_like(source), np.zeros_like(sink), neighbours, capacities)
    assert not everything[0].any()  # no terminal weights: nothing settles
    _, _, _, _, i, j, cost = everything
    graph = maxflow.Graph[float](len(pixels), len(i))
    nodes = graph.add_nodes(len(pixels))
    graph.add_edges(i, j, cost, cost)
    graph.add_grid_tedges(nodes, source, sink)
    graph.maxflow()
    flat = (distance > band).ravel()
    flat[pixels] = ~graph.get_grid_segments(nodes)
    plain = flat.reshape(h, w)
    e_found = energy(found, distance, band, image, probability)
    e_plain = energy(plain, distance, band, image, probability)
    assert e_found == pytest.approx(e_plain, rel=1e-9, abs=1e-9)
    side = settle(source, sink, neighbours, capacities)[0]
    settled = pixels[side != 0]
    # every settled pixel is where the plain flow put it
    np.testing.assert_array_equal(found.ravel()[settled], plain.ravel()[settled])


def disc_frame(radius: float, centre: tuple[float, float] = (80.0, 60.0)) -> tuple[U8, U8]:
    """A bright textured disc on a dark textured background, 120 x 160, and its mask."""
    rng = np.random.default_rng(0)
    h, w = 120, 160
    truth = contour_to_mask(circle_nodes(centre, radius, 720), (h, w))
    image = np.where(truth[..., None] > 0, [60, 160, 220], [90, 60, 30]).astype(np.float64)
    image += rng.normal(0, 6, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), truth


def global_maps(image: U8, p_object: float = 0.5) -> Maps:
    """Maps over the whole frame with an uninformative global p(object)."""
    h, w = image.shape[:2]
    return Maps((0, 0), np.full((h, w), p_object, np.float32), np.zeros((h, w), np.float32))


def test_the_cut_snaps_a_contour_that_is_off_to_the_edge() -> None:
    image, truth = disc_frame(30.0)
    off = circle_nodes((80.0, 60.0), 26.0, 128)  # the chain left it 4 pixels inside
    stage = BandCut(8)
    stage.start(image, circle_nodes((80.0, 60.0), 30.0, 128))
    found = stage.segment(image, global_maps(image), off, off)
    assert found is not None
    assert found.shape == (128, 2)
    before = mask_iou(contour_to_mask(off, truth.shape), truth)
    after = mask_iou(contour_to_mask(found, truth.shape), truth)
    assert before < 0.8 < 0.95 < after


def square_frame(lo: int, hi: int, size: int = 320) -> tuple[U8, U8]:
    """A bright textured square (rows and columns ``lo`` to ``hi - 1``) on a dark one."""
    rng = np.random.default_rng(0)
    truth = np.zeros((size, size), np.uint8)
    truth[lo:hi, lo:hi] = 1
    image = np.where(truth[..., None] > 0, [60, 160, 220], [90, 60, 30]).astype(np.float64)
    image += rng.normal(0, 6, image.shape)
    return np.clip(image, 0, 255).astype(np.uint8), truth


@pytest.mark.parametrize(("lo", "hi"), [(40, 279), (41, 279), (43, 277)])
def test_a_large_objects_edge_is_placed_to_the_pixel_by_the_second_cut(lo: int, hi: int) -> None:
    image, truth = square_frame(lo, hi)
    a, b = lo + 3.0, hi - 4.0  # the chain left it 3 pixels inside
    off = resample(np.array([[a, a], [b, a], [b, b], [a, b]]), 128, closed=True)
    assert _scale(off, 8) == 2  # cut at half resolution
    wrong = {}
    for fine in (False, True):
        stage = BandCut(8, fine=fine)
        stage.start(image, off)
        found = stage.segment(image, global_maps(image), off, off)
        assert found is not None
        wrong[fine] = np.count_nonzero((contour_to_mask(found, truth.shape) > 0) != (truth > 0))
    assert wrong[False] > 2 * (hi - lo)  # half a pixel off all round, or more
    assert wrong[True] <= 20  # a few pixels at the corners


def test_the_second_cut_is_only_for_large_objects() -> None:
    image, _ = disc_frame(30.0)
    off = circle_nodes((80.0, 60.0), 26.0, 128)
    found = []
    for fine in (False, True):
        stage = BandCut(8, fine=fine)
        stage.start(image, circle_nodes((80.0, 60.0), 30.0, 128))
        found.append(stage.segment(image, global_maps(image), off, off))
    np.testing.assert_array_equal(found[0], found[1])


def test_the_second_cut_moves_the_edge_by_at_most_its_band() -> None:
    rng = np.random.default_rng(1)
    region = rng.integers(0, 256, (200, 240, 3), dtype=np.uint8)
    piece = np.zeros((100, 120), bool)
    piece[30:70, 40:80] = True
    scaled = np.zeros((200, 240), np.uint8)
    scaled[60:140, 80:160] = 1
    square = np.ones((3, 3), np.uint8)
    grown = cv2.dilate(scaled, square, iterations=FINE_OUTSIDE) > 0
    shrunk = cv2.erode(scaled, square, iterations=FINE_INSIDE) > 0
    # the colours push out everywhere, or in
    for p, layers in ((0.999, FINE_OUTSIDE), (0.001, FINE_INSIDE)):
        found = _full_resolution(piece, region, np.full(piece.shape, p, np.float32), 256)
        mask = contour_to_mask(found, region.shape[:2]) > 0
        assert np.all(mask <= grown)
        assert np.all(mask >= shrunk)
        moved = np.count_nonzero(mask != (scaled > 0))
        assert moved > 0.75 * layers * 4 * 80  # it did move, as far as it may all round


def test_the_second_cut_reads_only_the_pieces_surroundings(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Its crop to the piece's box and FINE_MARGIN round it gives the cut of the whole
    region bit for bit (the region uncropped: a margin wider than the region)."""
    rng = np.random.default_rng(5)
    region = rng.integers(0, 256, (300, 340, 3), dtype=np.uint8)
    probability = rng.uniform(0.4, 0.999, (150, 170)).astype(np.float32)  # mostly outward
    piece = cv2.circle(np.zeros((150, 170), np.uint8), (80, 70), 40, 1, -1) > 0
    piece[60:75, 115:150] = True  # an arm out to the right
    cropped = _full_resolution(piece, region, probability, 128)
    monkeypatch.setattr(segmentation, "FINE_MARGIN", 1_000)
    np.testing.assert_array_equal(cropped, _full_resolution(piece, region, probability, 128))


def test_the_cut_moves_the_boundary_by_at_most_the_band() -> None:
    image, _ = disc_frame(55.0)
    small = circle_nodes((80.0, 60.0), 20.0, 128)
    stage = BandCut(5)
    stage.start(image, circle_nodes((80.0, 60.0), 55.0, 128))
    found = stage.segment(image, global_maps(image, 0.9), small, small)
    assert found is not None
    radii = np.hypot(*(found - [80.0, 60.0]).T)
    assert radii.max() <= 20.0 + 5.0 + 1.5  # the band, and rasterisation
    assert radii.mean() > 23.0  # and it did grow towards the edge


def test_no_cut_without_a_band_or_when_the_object_splits() -> None:
    image, _ = disc_frame(30.0)
    nodes = circle_nodes((80.0, 60.0), 30.0, 128)
    assert BandCut(0).segment(image, global_maps(image), nodes, nodes) is None
    # a bar 12 pixels thin, cut in two comparable pieces by a background-coloured gap
    from engine.geometry import resample

    bar = resample(np.array([[40.0, 54.0], [120.0, 54.0], [120.0, 66.0], [40.0, 66.0]]), 128)
    mask = contour_to_mask(bar, image.shape)
    split = np.where(mask[..., None] > 0, [60, 160, 220], [90, 60, 30]).astype(np.uint8)
    stage = BandCut(8)
    stage.start(split, bar)
    split[:, 76:85] = (90, 60, 30)
    probability = np.where(mask > 0, 0.9, 0.1).astype(np.float32)
    probability[:, 76:85] = 0.001
    maps = Maps((0, 0), probability, np.zeros_like(probability))
    assert stage.segment(split, maps, bar, bar) is None


def test_local_colour_tells_apart_what_the_global_model_cannot() -> None:
    """Object blue on its left half and red on its right; the background the other way round."""
    h, w = 100, 200
    image = np.zeros((h, w, 3), np.uint8)
    blue, red = (200, 40, 40), (40, 40, 200)
    image[:, :100] = red
    image[:, 100:] = blue
    box = np.array([[60.0, 30.0], [140.0, 30.0], [140.0, 70.0], [60.0, 70.0]])
    inside = contour_to_mask(box, (h, w)) > 0
    image[inside & (np.arange(w) < 100)] = blue
    image[inside & (np.arange(w) >= 100)] = red
    from engine.geometry import resample

    nodes = resample(box, 128)
    windows = LocalColour.learn(image, nodes)
    assert windows is not None
    fallback = np.full((h, w), 0.5, np.float32)  # global: both colours inside and out
    local = windows.probability(image, (0, 0), nodes, fallback, np.ones((h, w), np.uint8))
    near = cv2.dilate(inside.astype(np.uint8), np.ones((9, 9), np.uint8)) > 0
    left_object = inside & near & (np.arange(w) < 90)
    left_background = near & ~inside & (np.arange(w) < 60)
    assert local[left_object].mean() > 0.8
    assert local[left_background].mean() < 0.2
    restored = LocalColour.from_state(windows.to_state())
    np.testing.assert_array_equal(restored.object_counts, windows.object_counts)
    np.testing.assert_array_equal(restored.background_counts, windows.background_counts)


def test_the_stage_state_round_trips_and_checks_its_kind() -> None:
    image, _ = disc_frame(30.0)
    nodes = circle_nodes((80.0, 60.0), 30.0, 128)
    stage = BandCut(8)
    stage.start(image, nodes)
    restored = BandCut(8).from_state(stage.to_state())
    off = circle_nodes((80.0, 60.0), 27.0, 128)
    a = stage.segment(image, global_maps(image), off, off)
    b = restored.segment(image, global_maps(image), off, off)
    assert a is not None
    assert b is not None
    np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="band-cut"):
        BandCut(8).from_state({"kind": "grabcut"})


def test_the_tracker_follows_a_growing_thin_part() -> None:
    """A leg that grows out of the body: the cut pulls the contour into it."""
    h, w = 160, 200
    frames, masks = [], []
    for k in range(12):
        mask = contour_to_mask(circle_nodes((100.0, 60.0), 35.0, 360), (h, w))
        cv2.rectangle(mask, (96, 60), (104, 95 + 4 * k), 255, -1)
        image = np.where(mask[..., None] > 0, [50, 170, 230], [110, 70, 40]).astype(np.uint8)
        frames.append(image)
        masks.append(mask)
    from engine.geometry import mask_to_contour

    chain_only = Tracker(mask_to_contour(masks[0], 128), cut_band=0)
    with_cut = Tracker(mask_to_contour(masks[0], 128))
    for frame in frames:
        a, b = chain_only.step(frame), with_cut.step(frame)
    last = masks[-1]
    iou_chain = mask_iou(contour_to_mask(a.nodes, last.shape), last)
    iou_cut = mask_iou(contour_to_mask(b.nodes, last.shape), last)
    assert iou_cut >= 0.93
    assert iou_cut > iou_chain


@pytest.mark.parametrize("channels", [1, 3])
def test_the_window_kernels_bin_each_pixel_they_read_as_quantise_does(channels: int) -> None:
    """Windows counting from the image equal windows counting a precomputed bin map."""
    from engine.tracking._cut_kernels import learn_windows, local_probability

    rng = np.random.default_rng(channels)
    image = rng.integers(0, 256, (50, 60, channels), dtype=np.uint8)
    grey_bits, colour_bits = 5, 3
    bins = quantise(image[..., 0] if channels == 1 else image, grey_bits, colour_bits)
    n_bins = 1 << (grey_bits if channels == 1 else 3 * colour_bits)
    inside = (rng.random(bins.shape) < 0.4).astype(np.uint8)
    outside = (1 - inside) * (rng.random(bins.shape) < 0.7).astype(np.uint8)
    centres = np.array([[5, 5], [30, 20], [58, 48], [20, 40]], np.int64)
    fg, bg = learn_windows(image, grey_bits, colour_bits, inside, outside, centres, 8, n_bins)
    for n, (cx, cy) in enumerate(centres):
        window = np.s_[max(cy - 8, 0) : cy + 9, max(cx - 8, 0) : cx + 9]
        np.testing.assert_array_equal(
            fg[n], np.bincount(bins[window][inside[window] > 0], minlength=n_bins)
        )
        np.testing.assert_array_equal(
            bg[n], np.bincount(bins[window][outside[window] > 0], minlength=n_bins)
        )
    fallback = np.full(bins.shape, 0.5, np.float32)
    wanted = np.ones(bins.shape, np.uint8)
    p = local_probability(
        image, grey_bits, colour_bits, wanted, centres, 8, fg, bg, 12.0, 1.0, fallback
    )
    # a window's own colours: each pixel's p follows its bin's counts in the windows over it
    solo = local_probability(
        image, grey_bits, colour_bits, wanted, centres[:1], 8, fg[:1], bg[:1], 12.0, 1.0, fallback
    )
    y, x = 5, 5
    c = bins[y, x]
    pf = (fg[0, c] + 0.01) / (fg[0].sum() + 0.01 * n_bins)
    pb = (bg[0, c] + 0.01) / (bg[0].sum() + 0.01 * n_bins)
    seen = min((fg[0, c] + bg[0, c]) / 12.0, 1.0)
    assert solo[y, x] == pytest.approx(seen * pf / (pf + pb) + (1 - seen) * 0.5, rel=1e-5)
    assert p.shape == bins.shape
    assert np.all((p >= 0) & (p <= 1))
