"""engine.tracking.texture: grey frames described to the colour models by their texture."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, contour_to_mask, mask_iou
from engine.tracking import Tracker
from engine.tracking.texture import (
    GREY_TOLERANCE,
    TINT_KEPT,
    is_grey,
    is_tinted,
    texture_image,
)
from tests.engine.tracking.moving_disc import assert_same, through_json

U8 = NDArray[np.uint8]
W, H, R = 240, 180, 30.0
MEAN = 128.0
"""Object and background share this mean grey level: only their textures differ."""


def _texture(seed: int, cell: float, amplitude: float) -> NDArray[np.float32]:
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, 1.0, (2 * H, 2 * W)).astype(np.float32)
    smooth = np.asarray(cv2.GaussianBlur(noise, (0, 0), cell), np.float32)
    scaled: NDArray[np.float32] = smooth * np.float32(amplitude / smooth.std())
    return scaled


OBJECT = _texture(1, 1.0, 40.0)  # a fine, strong texture (fur, a patterned shirt)
BACKGROUND = _texture(2, 12.0, 40.0)  # as varied, but smooth (water, a wall): the same greys


def centre(t: int) -> tuple[float, float]:
    return 70.0 + 5.0 * t, 80.0 + 2.0 * t


def grey_frame(t: int) -> U8:
    """The textured disc at ``centre(t)`` (its texture moving with it) over the background."""
    cx, cy = centre(t)
    ys, xs = np.mgrid[0:H, 0:W]
    inside = (xs - cx) ** 2 + (ys - cy) ** 2 <= R**2
    shifted = OBJECT[H // 2 : H // 2 + H, W // 2 : W // 2 + W]
    moved = np.roll(shifted, (round(2.0 * t), round(5.0 * t)), axis=(0, 1))
    image = np.where(inside, MEAN + moved, MEAN + BACKGROUND[:H, :W])
    return np.asarray(np.clip(image, 0, 255), np.uint8)


FRAMES = [grey_frame(t) for t in range(24)]


def mean_iou(tracker: Tracker, frames: list[U8]) -> float:
    ious = []
    for t, frame in enumerate(frames):
        nodes = tracker.step(frame).nodes
        truth = contour_to_mask(circle_nodes(centre(t), R, 720), (H, W))
        ious.append(mask_iou(contour_to_mask(nodes, (H, W)), truth))
    return float(np.mean(ious[1:]))


def test_a_grey_frame_is_grey_and_a_coloured_one_is_not() -> None:
    grey = FRAMES[0]
    assert is_grey(grey)
    assert is_grey(np.dstack([grey, grey, grey]))
    noisy = np.dstack([grey, grey, np.clip(grey.astype(int) + GREY_TOLERANCE, 0, 255)])
    assert is_grey(noisy.astype(np.uint8))  # a grey source decoded with rounding
    coloured = np.dstack([grey, grey, grey]).copy()
    coloured[::7, ::7, 2] = 255 - coloured[::7, ::7, 2] // 2  # red where it is sampled
    assert not is_grey(coloured)


def sepia(grey: U8) -> U8:
    """A monochrome frame in a sepia tone: each channel an affine function of the grey."""
    level = grey.astype(np.float32)
    toned = np.dstack([0.80 * level + 8, 0.92 * level + 6, level + 4])
    return np.asarray(np.clip(np.rint(toned), 0, 255), np.uint8)


def through_a_codec(image: U8) -> U8:
    """As a video codec gives it back: YUV 4:2:0 (colour at half resolution), then JPEG."""
    yuv = cv2.cvtColor(image, cv2.COLOR_BGR2YUV_I420)
    back = cv2.cvtColor(yuv, cv2.COLOR_YUV2BGR_I420)
    ok, data = cv2.imencode(".jpg", back, [cv2.IMWRITE_JPEG_QUALITY, 75])
    assert ok
    return np.asarray(cv2.imdecode(data, cv2.IMREAD_COLOR), np.uint8)


def test_a_tinted_monochrome_frame_is_tinted_not_grey() -> None:
    tinted = sepia(FRAMES[0])
    assert not is_grey(tinted)  # its channels differ by up to 51 levels
    assert is_tinted(tinted)
    assert is_tinted(through_a_codec(tinted))  # the codec's colour smears across edges
    assert is_tinted(FRAMES[0])  # grey is one channel's levels too
    assert is_tinted(np.dstack([FRAMES[0]] * 3))


@pytest.mark.parametrize("side", [20, 60])
def test_a_coloured_object_in_a_tinted_scene_is_colour(side: int) -> None:
    """A small coloured object (20 px across) is enough: its colour is the best cue."""
    image = sepia(FRAMES[0]).copy()
    ys, xs = np.mgrid[0:H, 0:W]
    inside = (xs - 100) ** 2 + (ys - 90) ** 2 <= (side / 2) ** 2
    image[inside] = (40, 60, 200)  # red, BGR
    assert not is_tinted(image)
    assert not is_tinted(through_a_codec(image))


def test_a_colour_difference_of_a_few_levels_is_colour() -> None:
    """The generated ``matched_background``: beside the object, its grey level 8 levels
    bluer and 3 less red, on seed 19 otherwise nearly one channel's levels (10.6 levels
    off).  Read as grey, its track fell from J 0.979 to 0.786.  ``low_contrast``, whose
    object is the background's colour a little lighter or darker, is one channel's."""
    from engine.testing.synthetic import make_sequence

    matched = make_sequence("matched_background", seed=19, length=2).frames[0]
    assert not is_tinted(matched)
    assert is_tinted(make_sequence("low_contrast", seed=0, length=2).frames[0])


def test_two_flat_colours_are_colour() -> None:
    """Two colours lie on a line in any case (each channel is exactly affine in the grey
    level); orange on dark blue is no tint: its channels do not rise alike."""
    from tests.engine.scenes import body_with_legs

    frames, _ = body_with_legs(
        (120, 160), (80.0, 50.0), (80, 70), [[-10.0, 10.0]], length=40, width=8
    )
    assert not is_tinted(frames[0])
    assert not is_tinted(frames[0], TINT_KEPT)


@pytest.mark.parametrize("tolerance", [-1.0, math.nan, math.inf, True, "6"])
def test_is_tinted_refuses_a_tolerance_that_is_no_number_of_levels(tolerance: object) -> None:
    with pytest.raises(ValueError, match="tolerance must be"):
        is_tinted(FRAMES[0], tolerance)  # type: ignore[arg-type]


def test_the_texture_channels_read_edges_and_contrast() -> None:
    flat = np.full((40, 50), 90, np.uint8)
    out = texture_image(flat)
    assert out.shape == (40, 50, 3)
    assert out.dtype == np.uint8
    np.testing.assert_array_equal(out[..., 0], flat)  # the grey level itself
    assert not out[..., 1:].any()  # no edges, no contrast
    step = flat.copy()
    step[:, 25:] = 150  # a 60-level edge down the middle
    out = texture_image(step)
    assert out[20, 24, 1] > 8  # edge energy at the edge ...
    assert out[20, 5, 1] == 0  # ... none far from it
    assert out[20, 24, 2] > out[20, 5, 2]  # and contrast across it
    # the disc's fine texture against the smooth background, at equal mean grey
    tex = texture_image(FRAMES[0])
    cx, cy = (round(v) for v in centre(0))
    disc, far = tex[cy - 10 : cy + 10, cx - 10 : cx + 10], tex[:30, -60:]
    assert disc[..., 1].mean() > 2 * far[..., 1].mean()  # more edges ...
    assert disc[..., 2].mean() > 1.5 * far[..., 2].mean()  # ... and more contrast


def test_a_texture_told_from_its_surroundings_in_grey_is_followed() -> None:
    start = circle_nodes(centre(0), R, 64)
    with_texture = mean_iou(Tracker(start), FRAMES)
    grey_only = mean_iou(Tracker(start, grey_texture=False), FRAMES)
    assert with_texture >= 0.9
    assert with_texture > grey_only + 0.05  # the grey level alone does not tell them apart


def test_a_grey_frame_in_three_equal_channels_is_tracked_as_the_grey_one() -> None:
    start = circle_nodes(centre(0), R, 64)
    a, b = Tracker(start), Tracker(start)
    for frame in FRAMES[:6]:
        assert_same(a.step(frame), b.step(np.dstack([frame, frame, frame])))


def test_colour_frames_are_not_changed() -> None:
    colour = [np.asarray(cv2.applyColorMap(f, cv2.COLORMAP_JET), np.uint8) for f in FRAMES[:5]]
    start = circle_nodes(centre(0), R, 64)
    a, b = Tracker(start), Tracker(start, grey_texture=False)
    for frame in colour:
        assert_same(a.step(frame), b.step(frame))


def test_a_state_from_before_grey_texture_resumes_without_it() -> None:
    tracker = Tracker(circle_nodes(centre(0), R, 64), grey_texture=False)
    for frame in FRAMES[:3]:
        tracker.step(frame)
    state = through_json(tracker.to_state())
    del state["options"]["grey_texture"]
    restored = Tracker.from_state(state)
    assert not restored.options.grey_texture
    for frame in FRAMES[3:6]:
        assert_same(restored.step(frame), tracker.step(frame))


@pytest.mark.parametrize("value", [1, "on", None])
def test_grey_texture_must_be_true_or_false(value: object) -> None:
    with pytest.raises(ValueError, match="grey_texture must be true or false"):
        Tracker(circle_nodes(centre(0), R, 64), grey_texture=value)


@pytest.mark.parametrize(
    "frame",
    [
        np.zeros((4, 5, 3), np.uint8),
        np.zeros((4, 5), np.float32),
        np.zeros((0, 5), np.uint8),
        [[1, 2], [3, 4]],
    ],
)
def test_texture_image_refuses_what_is_not_a_grey_frame(frame: object) -> None:
    with pytest.raises(ValueError, match="texture_image takes"):
        texture_image(frame)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    "image", [np.zeros((4, 5, 4), np.uint8), np.zeros((4,), np.uint8), "frame"]
)
def test_is_grey_refuses_what_is_not_an_image(image: object) -> None:
    with pytest.raises(ValueError, match="is_grey takes"):
        is_grey(image)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="is_tinted takes"):
        is_tinted(image)  # type: ignore[arg-type]
