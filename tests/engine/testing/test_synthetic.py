"""Synthetic tracking sequences: shapes, determinism, and that each condition does what it says."""

from __future__ import annotations

from functools import cache

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.testing.synthetic import _OCCLUDER_BGR, CONDITIONS, SyntheticSequence, make_sequence

SMALL = (144, 192)
KERNEL = np.ones((5, 5), np.uint8)


@cache
def small(condition: str, seed: int = 0) -> SyntheticSequence:
    return make_sequence(condition, seed=seed, length=6, size=SMALL)


def grey(frame: NDArray[np.uint8]) -> NDArray[np.float64]:
    return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.float64)


def centroid(mask: NDArray[np.uint8]) -> NDArray[np.float64]:
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()])


def steps(seq: SyntheticSequence) -> NDArray[np.float64]:
    c = np.array([centroid(m) for m in seq.masks])
    return np.asarray(np.hypot(*np.diff(c, axis=0).T), np.float64)


@pytest.mark.parametrize("condition", CONDITIONS)
def test_shapes_dtypes_and_masks_inside_frame(condition: str) -> None:
    seq = small(condition)
    assert seq.condition == condition
    assert len(seq) == len(seq.frames) == len(seq.masks) == 6
    H, W = SMALL
    for frame, mask in zip(seq.frames, seq.masks, strict=True):
        assert frame.shape == (H, W, 3)
        assert frame.dtype == np.uint8
        assert mask.shape == (H, W)
        assert mask.dtype == np.uint8
        assert set(np.unique(mask)) == {0, 255}
        ys, xs = np.nonzero(mask)
        assert min(ys.min(), xs.min()) >= 10
        assert ys.max() <= H - 11
        assert xs.max() <= W - 11
        assert not frame.flags.writeable
        assert not mask.flags.writeable


@pytest.mark.parametrize("condition", CONDITIONS)
def test_deterministic_per_seed(condition: str) -> None:
    a = small(condition, 3)
    b = make_sequence(condition, seed=3, length=6, size=SMALL)
    c = small(condition, 4)
    for fa, fb, ma, mb in zip(a.frames, b.frames, a.masks, b.masks, strict=True):
        np.testing.assert_array_equal(fa, fb)
        np.testing.assert_array_equal(ma, mb)
    assert not np.array_equal(a.frames[0], c.frames[0])
    assert not np.array_equal(a.masks[0], c.masks[0])


@pytest.mark.parametrize("condition", ["plain", "motion_blur", "matched_background"])
def test_shorter_sequence_is_a_prefix(condition: str) -> None:
    short = make_sequence(condition, seed=5, length=3, size=SMALL)
    for a, b in zip(short.frames, small(condition, 5).frames[:3], strict=True):
        np.testing.assert_array_equal(a, b)


def test_conditions_differ_for_the_same_seed() -> None:
    assert not np.array_equal(small("plain").masks[0], small("noise").masks[0])


@pytest.mark.parametrize("condition", CONDITIONS)
def test_object_moves(condition: str) -> None:
    assert steps(small(condition)).mean() >= 1.0


def test_plain_speed_is_moderate() -> None:
    d = steps(make_sequence("plain", seed=1, length=8))
    assert 1.5 <= d.mean() <= 6.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fast_motion_moves_at_least_15_px_per_frame(seed: int) -> None:
    assert steps(make_sequence("fast_motion", seed=seed, length=8)).mean() >= 15.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_scale_change_changes_the_area_by_1_6(seed: int) -> None:
    areas = [np.count_nonzero(m) for m in small("scale_change", seed).masks]
    assert max(areas[0] / areas[-1], areas[-1] / areas[0]) >= 1.6


def test_shape_change_deforms_more_than_plain() -> None:
    def spread(seq: SyntheticSequence) -> float:
        # relative spread of the boundary's distance to the centroid, averaged over frames
        out = []
        for m in seq.masks:
            found, _ = cv2.findContours(m, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
            pts = found[0].reshape(-1, 2).astype(np.float64)
            r = np.hypot(*(pts - centroid(m)).T)
            out.append(r.std() / r.mean())
        return float(np.mean(out))

    seqs = [
        make_sequence(c, seed=s, length=20, size=SMALL)
        for s in (0, 1)
        for c in ("plain", "shape_change")
    ]
    assert spread(seqs[1]) > 2 * spread(seqs[0])
    assert spread(seqs[3]) > 2 * spread(seqs[2])


def test_occluder_covers_part_of_the_object_in_some_frames_only() -> None:
    seq = small("occluder")
    counts = []
    for frame, mask in zip(seq.frames, seq.masks, strict=True):
        inner = cv2.erode(mask, KERNEL) > 0
        close = np.abs(frame.astype(np.float64) - _OCCLUDER_BGR).max(axis=2) < 20
        counts.append(int(np.count_nonzero(close & inner)))
    assert counts[0] == 0
    assert counts[-1] == 0
    assert max(counts) >= 30
    # the mask is amodal: the occluder does not cut it
    areas = [np.count_nonzero(m) for m in seq.masks]
    assert max(areas) < 1.2 * min(areas)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_low_contrast_object_differs_by_a_few_grey_levels(seed: int) -> None:
    seq = small("low_contrast", seed)
    for frame, mask in zip(seq.frames, seq.masks, strict=True):
        g = grey(frame)
        inner = cv2.erode(mask, KERNEL) > 0
        ring = (cv2.dilate(mask, KERNEL, iterations=3) > 0) & ~(cv2.dilate(mask, KERNEL) > 0)
        assert 8.0 <= abs(g[inner].mean() - g[ring].mean()) <= 25.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_matched_background_left_half_has_the_objects_grey(seed: int) -> None:
    seq = small("matched_background", seed)
    W = SMALL[1]
    on_left = []
    for frame, mask in zip(seq.frames, seq.masks, strict=True):
        g = grey(frame)
        away = ~(cv2.dilate(mask, KERNEL, iterations=2) > 0)
        left, right = away.copy(), away.copy()
        left[:, W // 2 - 10 :] = False
        right[:, : W // 2 + 10] = False
        obj = g[mask > 0].mean()
        assert abs(obj - g[left].mean()) <= 10.0
        assert abs(obj - g[right].mean()) >= 40.0
        on_left.append(np.count_nonzero(mask[:, : W // 2]) / np.count_nonzero(mask))
    assert max(on_left) >= 0.25


def test_textured_interior_has_strong_texture() -> None:
    def interior_std(seq: SyntheticSequence) -> float:
        m = cv2.erode(seq.masks[0], KERNEL) > 0
        return float(grey(seq.frames[0])[m].std())

    assert interior_std(small("textured")) > 20.0
    assert interior_std(small("plain")) < 8.0


def test_noise_levels_are_ordered() -> None:
    def residual(condition: str) -> float:
        seq = small(condition)
        g = grey(seq.frames[0])
        away = cv2.dilate(seq.masks[0], KERNEL, iterations=3) == 0
        return float((g - cv2.GaussianBlur(g, (0, 0), 2.0))[away].std())

    # grey sigma is about 0.67 of the per-channel sigma (2, 10, 25), a little less after the blur
    plain, noise, strong = residual("plain"), residual("noise"), residual("strong_noise")
    assert plain < 2.5 < noise < 10.0 < strong


def test_clutter_adds_strong_edges_near_the_object() -> None:
    def edges(condition: str) -> int:
        seq = make_sequence(condition, seed=0, length=6)
        total = 0
        for frame, mask in zip(seq.frames, seq.masks, strict=True):
            near = cv2.dilate(mask, KERNEL, iterations=10) > 0
            near &= ~(cv2.dilate(mask, KERNEL, iterations=2) > 0)
            total += int(np.count_nonzero(cv2.Canny(frame, 50, 150)[near]))
        return total

    assert edges("clutter") > 200 > 10 * edges("plain")


def test_motion_blur_softens_the_object_edge() -> None:
    def edge_sharpness(condition: str) -> float:
        # mean gradient on the outline per grey level of object/background contrast
        seq = make_sequence(condition, seed=0, length=4)
        g, m = grey(seq.frames[2]), seq.masks[2]
        grad = np.hypot(cv2.Sobel(g, cv2.CV_64F, 1, 0), cv2.Sobel(g, cv2.CV_64F, 0, 1))
        edge = cv2.morphologyEx(m, cv2.MORPH_GRADIENT, KERNEL) > 0
        inner = cv2.erode(m, KERNEL, iterations=3) > 0
        ring = (cv2.dilate(m, KERNEL, iterations=5) > 0) & ~(
            cv2.dilate(m, KERNEL, iterations=3) > 0
        )
        return float(grad[edge].mean() / abs(g[inner].mean() - g[ring].mean()))

    assert edge_sharpness("motion_blur") < 0.85 * edge_sharpness("plain")


@pytest.mark.parametrize(
    ("condition", "kwargs", "match"),
    [
        ("snow", {}, "unknown condition"),
        ("plain", {"length": 1}, "length"),
        ("plain", {"length": 0}, "length"),
        ("plain", {"size": (50, 640)}, "size"),
        ("plain", {"size": (480, 95)}, "size"),
        ("plain", {"size": (480,)}, "size"),
        ("plain", {"seed": -1}, "seed"),
    ],
)
def test_bad_arguments_raise_value_error(
    condition: str, kwargs: dict[str, object], match: str
) -> None:
    with pytest.raises(ValueError, match=match):
        make_sequence(condition, **kwargs)  # type: ignore[arg-type]
