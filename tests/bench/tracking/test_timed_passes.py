"""The tracking benchmark times its timed set in several passes and checks they agree."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from bench.common.data import davis_names
from bench.tracking.config import TIMED_PASSES
from bench.tracking.goals import (
    MEDIAN_MS_GOAL,
    SPEEDUP_GOAL,
    fastest,
    repeat_goal,
    speed_goals,
)
from bench.tracking.run import ClipResult, TrackRun, same_tracks


def clip(name: str, shift: float = 0.0) -> ClipResult:
    nodes = [np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]]) + shift for _ in range(3)]
    return ClipResult(name, "davis-val", 3, (8, 8), {"efdm": TrackRun("efdm", 3, 3, nodes=nodes)})


def test_the_timed_set_runs_more_than_once() -> None:
    assert TIMED_PASSES >= 2


def test_passes_with_equal_contours_are_the_same_and_a_bit_of_difference_is_not() -> None:
    assert same_tracks([clip("a"), clip("b")], [clip("a"), clip("b")])
    assert not same_tracks([clip("a")], [clip("a", shift=1e-12)])
    assert not same_tracks([clip("a")], [clip("b")])
    assert not same_tracks([clip("a")], [clip("a"), clip("b")])


def test_the_speed_goals_take_each_trackers_fastest_pass() -> None:
    passes = {"efdm": [12.0, 9.0], "skimage": [80.0, 90.0]}
    assert fastest(passes, "efdm") == 9.0
    assert math.isnan(fastest(passes, "static"))
    speedup, frame = speed_goals(passes, "davis-val 480p")
    assert speedup.measured == 80.0 / 9.0
    assert frame.measured == 9.0
    assert frame.passed is (MEDIAN_MS_GOAL >= 9.0)
    assert "12.00 / 9.00" in frame.shown


def test_a_speed_up_just_under_the_goal_is_not_shown_as_the_goal() -> None:
    efdm_ms = 7.01
    speedup, _ = speed_goals({"efdm": [efdm_ms], "skimage": [SPEEDUP_GOAL * efdm_ms - 0.1]}, "x")
    assert speedup.passed is False
    assert speedup.shown.startswith(f"{SPEEDUP_GOAL - 0.01:.2f}x")


def test_passes_that_differ_fail_the_repeat_goal() -> None:
    assert repeat_goal(True, 2, "here").passed
    assert not repeat_goal(False, 2, "here").passed


def test_a_quick_synthetic_run_times_twice_and_takes_the_seeds_asked_for(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "synthetic", "--trackers", "efdm", "--seeds", "2"]
    assert BENCHMARK.main([*args, "--sequences", "plain@1", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "tracking.json").read_text())
    assert [clip["name"] for clip in data["sets"]["synthetic"]] == ["plain@1"]
    assert len(data["timed_pass_median_ms"]["efdm"]) == TIMED_PASSES
    assert data["timed_passes_identical"] is True
    assert "the same contours in each of 2 passes" in (tmp_path / "tracking.md").read_text()


def test_synthetic_clips_take_the_length_asked_for(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "synthetic", "--trackers", "efdm", "--length", "7"]
    assert BENCHMARK.main([*args, "--sequences", "hidden", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "tracking.json").read_text())
    assert [clip["frames"] for clip in data["sets"]["synthetic"]] == [7]
    assert "(synthetic clips of 7 frames)" in (tmp_path / "tracking.md").read_text()


@pytest.mark.parametrize("length", ["2", "0", "x"])
def test_a_synthetic_length_below_three_is_refused(tmp_path: Path, length: str) -> None:
    from bench.tracking.main import BENCHMARK

    with pytest.raises(SystemExit) as exit_info:
        BENCHMARK.main(["--quick", "--length", length, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert not (tmp_path / "tracking.json").exists()


def test_seeds_below_one_are_refused(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    with pytest.raises(SystemExit) as exit_info:
        BENCHMARK.main(["--quick", "--seeds", "0", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert not (tmp_path / "tracking.json").exists()


def test_resized_brings_frames_and_masks_to_the_shape_asked_for() -> None:
    from bench.common.data import Clip
    from bench.tracking.sets import resized

    frame = np.zeros((8, 12, 3), np.uint8)
    frame[2:6, 3:9] = 200
    mask = np.zeros((8, 12), np.uint8)
    mask[2:6, 3:9] = 255
    clip = Clip("a", "davis-val", (frame, frame), (mask, mask))
    assert resized(clip, (8, 12)) is clip
    big = resized(clip, (12, 18))
    assert [f.shape for f in big.frames] == [(12, 18, 3)] * 2
    assert [m.shape for m in big.masks] == [(12, 18)] * 2
    assert set(np.unique(big.masks[0])) == {0, 255}  # still a mask: nearest pixel
    assert np.count_nonzero(big.masks[0]) == pytest.approx(1.5**2 * 24, rel=0.25)
    small = resized(clip, (4, 6))
    assert small.frames[0].shape == (4, 6, 3)
    assert small.frames[0][2, 3, 0] == 200  # areas averaged: inside stays inside


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_davis_clips_take_the_resize_asked_for(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "davis-val", "--trackers", "efdm", "--resize", "1.5"]
    assert BENCHMARK.main([*args, "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "tracking.json").read_text())
    clips = data["sets"]["davis-val"]
    assert clips
    assert all(clip["shape"] == [720, 1281] for clip in clips)  # 480 x 854, by 1.5
    text = (tmp_path / "tracking.md").read_text()
    assert "DAVIS frames and masks resized by 1.5" in text
    assert "davis-val 720p" in text  # the speed goals name the frames' size


@pytest.mark.parametrize(
    ("flag", "value"),
    [
        *(("--resize", v) for v in ("0.2", "5", "x", "nan")),
        *(("--noise", v) for v in ("-1", "65", "x", "nan")),
    ],
)
def test_a_view_out_of_range_is_refused(tmp_path: Path, flag: str, value: str) -> None:
    from bench.tracking.main import BENCHMARK

    with pytest.raises(SystemExit) as exit_info:
        BENCHMARK.main(["--quick", flag, value, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert not (tmp_path / "tracking.json").exists()


def test_a_grey_clip_has_grey_frames_and_the_same_masks() -> None:
    from bench.tracking.sets import ClipSpec

    names = davis_names()
    if not names:
        pytest.skip("no DAVIS validation sequences here")
    colour = ClipSpec("davis-val", names[0], 3).load()
    grey = ClipSpec("davis-val", names[0], 3, grey=True).load()
    assert [f.shape for f in grey.frames] == [f.shape[:2] for f in colour.frames]
    for a, b in zip(grey.masks, colour.masks, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_tinted_clip_is_one_channel_in_colour_and_has_the_same_masks() -> None:
    from bench.tracking.sets import ClipSpec
    from engine.tracking.texture import is_grey, is_tinted

    names = davis_names()
    if not names:
        pytest.skip("no DAVIS validation sequences here")
    colour = ClipSpec("davis-val", names[0], 3).load()
    tinted = ClipSpec("davis-val", names[0], 3, tint=True).load()
    for frame, plain in zip(tinted.frames, colour.frames, strict=True):
        assert frame.shape == plain.shape
        assert is_tinted(frame)
        assert not is_grey(frame)
        assert not is_tinted(plain)
    for a, b in zip(tinted.masks, colour.masks, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_tinted_frame_of_odd_sides_keeps_its_size() -> None:
    from bench.tracking.sets import tinted_frame

    frame = np.random.default_rng(0).integers(0, 256, (7, 9, 3), dtype=np.uint8)
    out = tinted_frame(frame)
    assert out.shape == (7, 9, 3)
    assert out.dtype == np.uint8


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_a_grey_run_says_so(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "davis-val", "--trackers", "efdm", "--grey"]
    assert BENCHMARK.main([*args, "--sequences", davis_names()[0], "--out", str(tmp_path)]) == 0
    assert "DAVIS frames in grey" in (tmp_path / "tracking.md").read_text()


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_a_tinted_run_says_so(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "davis-val", "--trackers", "efdm", "--tint"]
    assert BENCHMARK.main([*args, "--sequences", davis_names()[0], "--out", str(tmp_path)]) == 0
    assert "sepia tone" in (tmp_path / "tracking.md").read_text()


def test_a_noisy_clip_has_the_same_noise_on_every_load_and_the_same_masks() -> None:
    from bench.tracking.sets import ClipSpec

    names = davis_names()
    if not names:
        pytest.skip("no DAVIS validation sequences here")
    colour = ClipSpec("davis-val", names[0], 3).load()
    noisy = ClipSpec("davis-val", names[0], 3, noise=8.0).load()
    again = ClipSpec("davis-val", names[0], 3, noise=8.0).load()
    for frame, plain, same in zip(noisy.frames, colour.frames, again.frames, strict=True):
        np.testing.assert_array_equal(frame, same)
        difference = frame.astype(np.float64) - plain
        assert abs(difference.mean()) < 0.5  # zero-mean noise
        assert 6.0 < difference.std() < 8.5  # of 8 levels (fewer where clipped)
    # each frame draws its own noise
    first = noisy.frames[0].astype(np.float64) - colour.frames[0]
    second = noisy.frames[1].astype(np.float64) - colour.frames[1]
    assert abs(np.corrcoef(first.ravel(), second.ravel())[0, 1]) < 0.1
    for a, b in zip(noisy.masks, colour.masks, strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_a_strided_clip_keeps_one_frame_and_mask_in_k_from_the_first() -> None:
    from bench.tracking.sets import ClipSpec

    name = davis_names()[0]
    every = ClipSpec("davis-val", name, 7).load()
    strided = ClipSpec("davis-val", name, 7, stride=3).load()
    assert len(strided.frames) == len(strided.masks) == len(strided.visible) == 3
    for k, index in enumerate((0, 3, 6)):
        np.testing.assert_array_equal(strided.frames[k], every.frames[index])
        np.testing.assert_array_equal(strided.masks[k], every.masks[index])


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_a_strided_run_says_so_and_scores_the_strided_clip(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    name = davis_names()[0]
    args = ["--quick", "--sets", "davis-val", "--trackers", "static", "--stride", "2"]
    assert BENCHMARK.main([*args, "--sequences", name, "--out", str(tmp_path)]) == 0
    assert "one DAVIS frame in 2 tracked and scored" in (tmp_path / "tracking.md").read_text()
    (clip,) = json.loads((tmp_path / "tracking.json").read_text())["sets"]["davis-val"]
    assert clip["frames"] == 8  # --quick's first 15 frames, one in two
    assert (tmp_path / f"tracking_sheet_davis_{name}.jpg").exists()


@pytest.mark.parametrize("value", ["0", "9", "1.5", "x"])
def test_a_stride_out_of_range_is_refused(tmp_path: Path, value: str) -> None:
    from bench.tracking.main import BENCHMARK

    with pytest.raises(SystemExit) as exit_info:
        BENCHMARK.main(["--quick", "--stride", value, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert not (tmp_path / "tracking.json").exists()


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
@pytest.mark.parametrize("codec", ["mp4v", "vp8"])
def test_a_coded_clip_is_close_the_same_on_every_load_and_keeps_its_masks(codec: str) -> None:
    from bench.tracking.sets import ClipSpec

    name = davis_names()[0]
    plain = ClipSpec("davis-val", name, 3).load()
    coded = ClipSpec("davis-val", name, 3, codec=codec).load()
    again = ClipSpec("davis-val", name, 3, codec=codec).load()
    assert len(coded.frames) == 3
    for frame, original, same in zip(coded.frames, plain.frames, again.frames, strict=True):
        assert frame.shape == original.shape
        assert frame.dtype == np.uint8
        np.testing.assert_array_equal(frame, same)  # deterministic encoders
        assert not np.array_equal(frame, original)  # lossy
        assert 30.0 < cv2.PSNR(frame, original) < 60.0
    for a, b in zip(coded.masks, plain.masks, strict=True):
        np.testing.assert_array_equal(a, b)


def test_a_grey_clip_through_a_codec_stays_grey() -> None:
    from bench.tracking.sets import coded

    rng = np.random.default_rng(1)
    frames = [
        np.asarray(
            cv2.GaussianBlur(rng.integers(0, 256, (48, 64), dtype=np.uint8), (5, 5), 1), np.uint8
        )
        for _ in range(3)
    ]
    out = coded(frames, "mp4v")
    assert [f.shape for f in out] == [(48, 64)] * 3
    with pytest.raises(ValueError, match="codec must be one of"):
        coded(frames, "h264")


@pytest.mark.skipif(not davis_names(), reason="no DAVIS validation sequences here")
def test_a_coded_run_says_so(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    args = ["--quick", "--sets", "davis-val", "--trackers", "static", "--codec", "vp8"]
    assert BENCHMARK.main([*args, "--sequences", davis_names()[0], "--out", str(tmp_path)]) == 0
    assert "DAVIS frames through vp8 video" in (tmp_path / "tracking.md").read_text()


def test_an_unknown_codec_is_refused(tmp_path: Path) -> None:
    from bench.tracking.main import BENCHMARK

    with pytest.raises(SystemExit) as exit_info:
        BENCHMARK.main(["--quick", "--codec", "h264", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert not (tmp_path / "tracking.json").exists()
