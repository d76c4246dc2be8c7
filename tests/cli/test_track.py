"""``efdm track`` end to end: a dark disc moving across a light background."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from efdm_cli import EXIT_INVALID, EXIT_IO, main

T, W, H, R = 12, 160, 120, 18  # frames, width, height, disc radius
CIRCLE = f"40,60,{R}"  # the disc on frame 0
POLYGON = "22,42 58,42 58,78 22,78"  # the square around it


def disc_centre(i: int) -> tuple[float, float]:
    """Where the disc is on frame ``i``: 5 px right and 1 px down per frame."""
    return 40.0 + 5.0 * i, 60.0 + 1.0 * i


def disc_frame(i: int, size: tuple[int, int] = (W, H)) -> NDArray[np.uint8]:
    """A light BGR frame with a dark disc, mildly noisy (fixed seed)."""
    w, h = size
    rng = np.random.default_rng(i)
    frame = np.clip(200 + rng.normal(0, 4, (h, w, 3)), 0, 255).astype(np.uint8)
    cx, cy = disc_centre(i)
    cv2.circle(frame, (round(cx * 16), round(cy * 16)), R * 16, (40, 50, 60), -1, cv2.LINE_AA, 4)
    return frame


@pytest.fixture(scope="module")
def video(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("video") / "disc.mp4"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), 10.0, (W, H))
    assert writer.isOpened()
    for i in range(T):
        writer.write(disc_frame(i))
    writer.release()
    assert video_info(path) == (T, W, H)  # the test input itself is readable
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("frames")
    for i in range(T):
        assert cv2.imwrite(str(path / f"frame_{i:03d}.png"), disc_frame(i))
    (path / "notes.txt").write_text("not an image, ignored")
    return path


def video_info(path: Path) -> tuple[int, int, int]:
    """(frames decoded, width, height) of a video file."""
    capture = cv2.VideoCapture(str(path))
    assert capture.isOpened()
    count, size = 0, (0, 0)
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        count, size = count + 1, (frame.shape[1], frame.shape[0])
    capture.release()
    return count, *size


def read_records(text: str, nodes: int = 128) -> list[dict[str, Any]]:
    """Parse JSON Lines and check every record's form."""
    records = [json.loads(line) for line in text.splitlines()]
    assert [r["frame"] for r in records] == list(range(len(records)))
    for r in records:
        assert set(r) == {
            "frame",
            "nodes",
            "iterations",
            "converged",
            "confidence",
            "status",
            "elapsed_ms",
        }
        arr = np.array(r["nodes"], dtype=np.float64)
        assert arr.shape == (nodes, 2)
        assert np.isfinite(arr).all()
        assert isinstance(r["iterations"], int)
        assert isinstance(r["converged"], bool)
        assert 0.0 <= r["confidence"] <= 1.0
        assert r["status"] in {"tracking", "uncertain", "lost"}
        assert r["elapsed_ms"] >= 0
    return records


def test_video_with_overlay(video: Path, tmp_path: Path) -> None:
    out, overlay = tmp_path / "tracks.jsonl", tmp_path / "overlay.mp4"
    argv = ["track", str(video), "--init-circle", CIRCLE, "--out", str(out)]
    assert main([*argv, "--overlay", str(overlay), "--quiet"]) == 0
    records = read_records(out.read_text())
    assert len(records) == T
    np.testing.assert_allclose(np.mean(records[0]["nodes"], axis=0), [40, 60], atol=1e-3)
    assert video_info(overlay) == (T, W, H)


def test_the_contour_follows_the_disc(video: Path, tmp_path: Path) -> None:
    out = tmp_path / "tracks.jsonl"
    assert main(["track", str(video), "--init-circle", CIRCLE, "-o", str(out), "-q"]) == 0
    for r in read_records(out.read_text()):
        nodes = np.array(r["nodes"])
        centroid = nodes.mean(axis=0)  # nodes are evenly spaced along the contour
        assert np.hypot(*(centroid - disc_centre(r["frame"]))) < 2.0, r["frame"]
        radius = np.hypot(*(nodes - centroid).T).mean()
        assert abs(radius - R) < 3.0, r["frame"]


def test_folder_to_stdout(folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["track", str(folder), "--init-polygon", POLYGON, "--nodes", "40"]) == 0
    captured = capsys.readouterr()
    records = read_records(captured.out, nodes=40)
    assert len(records) == T
    assert captured.err == ""  # short input: no progress line


def test_the_help_names_every_field_of_a_record(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["track", str(folder), "--init-circle", CIRCLE, "--quiet"]) == 0
    record = read_records(capsys.readouterr().out)[0]
    with pytest.raises(SystemExit):
        main(["track", "--help"])
    described = " ".join(capsys.readouterr().out.split())  # argparse wraps the text
    for field in record:
        assert field in described, field
    for status in ("tracking", "uncertain", "lost"):
        assert status in described


def test_glob_pattern_with_mask(folder: Path, tmp_path: Path) -> None:
    mask = np.zeros((H, W), np.uint8)
    cv2.circle(mask, (40, 60), R, 255, -1)
    assert cv2.imwrite(str(tmp_path / "mask.png"), mask)
    frames = tmp_path / "frames"
    frames.mkdir()
    for p in sorted(folder.glob("*.png"))[:5]:
        shutil.copy(p, frames / p.name)
    (frames / "other.jpg").write_bytes(b"not matched by the pattern")
    out = tmp_path / "t.jsonl"
    pattern = str(frames / "frame_*.png")
    argv = ["track", pattern, "--init-mask", str(tmp_path / "mask.png"), "-n", "64"]
    assert main([*argv, "-o", str(out), "-q"]) == 0
    records = read_records(out.read_text(), nodes=64)
    assert len(records) == 5
    np.testing.assert_allclose(np.mean(records[0]["nodes"], axis=0), [40, 60], atol=1.0)


def test_overlay_of_an_image_folder_runs_at_25_fps(folder: Path, tmp_path: Path) -> None:
    overlay = tmp_path / "o.mp4"
    argv = ["track", str(folder), "--init-circle", CIRCLE, "-o", str(tmp_path / "t.jsonl")]
    assert main([*argv, "--overlay", str(overlay), "--stiffness", "5"]) == 0
    capture = cv2.VideoCapture(str(overlay))
    assert capture.get(cv2.CAP_PROP_FPS) == pytest.approx(25.0)
    capture.release()


def test_console_entry_in_a_real_process(folder: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "efdm_cli", "track", str(folder / "*.png"),
         "--init-circle", CIRCLE, "--nodes", "32"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert len(read_records(proc.stdout, nodes=32)) == T


def test_error_in_a_real_process(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "efdm_cli", "track", str(tmp_path / "none.mp4"),
         "--init-circle", CIRCLE],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode == EXIT_IO
    assert proc.stdout == ""
    assert proc.stderr.startswith("efdm track: error: cannot read")


def _error(capsys: pytest.CaptureFixture[str], argv: list[str], code: int) -> str:
    assert main(argv) == code
    err = capsys.readouterr().err
    assert err.startswith("efdm track: error: ")
    return err


@pytest.mark.parametrize(
    ("init", "message"),
    [
        ([], "exactly one of --init-mask, --init-box, --init-polygon, --init-circle (got none)"),
        (["--init-box", "10,10,5,20"], "x1 > x0 and y1 > y0"),
        (["--init-box", "10,10,20"], "x0,y0,x1,y1"),
        (["--init-box", "300,300,320,330"], "outside the frame (160 x 120)"),
        (["--init-box", "10,10,30,30", "--init-circle", CIRCLE], "--init-box and --init-circle"),
        (["--init-circle", CIRCLE, "--init-polygon", POLYGON], "--init-polygon and --init-circle"),
        (["--init-circle", "40,60"], "cx,cy,r"),
        (["--init-circle", "40,60,-3"], "r > 0"),
        (["--init-circle", "a,b,c"], "not a comma-separated list of numbers"),
        (["--init-circle", "40,60,nan"], "non-finite"),
        (["--init-polygon", "1,2 3,4"], "at least 3 points"),
        (["--init-polygon", "1,2 3,4 5"], '"x,y x,y ..."'),
        (["--init-polygon", "1,1 2,2 3,3"], "encloses no area"),
        (["--init-circle", CIRCLE, "--nodes", "2"], "--nodes must be in [3, 4096]"),
        (["--init-box", "10,10,30,30", "--min-piece-area", "-5"], "--min-piece-area must be"),
        (["--init-circle", CIRCLE, "--min-piece-area", "50"], "give --init-mask, or snap"),
        (["--init-circle", CIRCLE, "--nodes", "33000"], "--nodes must be in [3, 4096]"),
        (["--init-circle", CIRCLE, "--nodes", "100000000"], "--nodes must be in [3, 4096]"),
        (["--init-circle", "500,60,10"], "initial contour lies outside the frame (160 x 120)"),
        (["--init-polygon", "-30,-30 -10,-30 -10,-10"], "outside the frame (160 x 120)"),
        (["--init-circle", CIRCLE, "--stiffness", "-1"], "stiffness"),
        (["--init-circle", CIRCLE, "-O", "no_such_option=1"], "no_such_option"),
        (["--init-circle", CIRCLE, "-O", "iterations=0"], "iterations"),
        (["--init-circle", CIRCLE, "-O", "nonsense"], "KEY=VALUE"),
    ],
)
def test_invalid_arguments_exit_2(
    folder: Path, capsys: pytest.CaptureFixture[str], init: list[str], message: str
) -> None:
    assert message in _error(capsys, ["track", str(folder), *init], EXIT_INVALID)


def test_a_circle_around_the_whole_frame_is_not_outside(folder: Path, tmp_path: Path) -> None:
    argv = ["track", str(folder / "frame_00[01].png"), "--init-circle", "80,60,400", "-q"]
    assert main([*argv, "-o", str(tmp_path / "t.jsonl")]) == 0


def test_mask_errors(folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty, small = tmp_path / "empty.png", tmp_path / "small.png"
    assert cv2.imwrite(str(empty), np.zeros((H, W), np.uint8))
    assert cv2.imwrite(str(small), np.full((10, 10), 255, np.uint8))
    track = ["track", str(folder), "--init-mask"]
    assert "no object pixels" in _error(capsys, [*track, str(empty)], EXIT_INVALID)
    assert "is 10 x 10" in _error(capsys, [*track, str(small)], EXIT_INVALID)
    assert "cannot read" in _error(capsys, [*track, str(tmp_path / "nope.png")], EXIT_IO)


def test_frame_size_changing_mid_stream(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    for p in sorted(folder.glob("*.png"))[:4]:
        shutil.copy(p, frames / p.name)
    assert cv2.imwrite(str(frames / "frame_004.png"), disc_frame(4, (W + 8, H)))
    out = tmp_path / "t.jsonl"
    argv = ["track", str(frames), "--init-circle", CIRCLE, "-o", str(out)]
    err = _error(capsys, argv, EXIT_INVALID)
    assert "frame 4" in err
    assert "frame_004.png" in err
    assert "168 x 120, but the first frame is 160 x 120" in err
    assert len(read_records(out.read_text())) == 4  # the frames before it were written


@pytest.mark.parametrize("content", [b"", b"garbage, not a PNG"])
def test_undecodable_image_in_a_folder_is_named(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes
) -> None:
    frames = tmp_path / "frames"
    frames.mkdir()
    shutil.copy(folder / "frame_000.png", frames)
    (frames / "frame_001.png").write_bytes(content)
    argv = ["track", str(frames), "--init-circle", CIRCLE, "-o", str(tmp_path / "t.jsonl")]
    err = _error(capsys, argv, EXIT_IO)
    assert f"cannot decode image {frames / 'frame_001.png'}" in err


def test_io_errors_exit_1(
    folder: Path, video: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    init = ["--init-circle", CIRCLE]
    (tmp_path / "empty").mkdir()
    (tmp_path / "bad.mp4").write_bytes(b"this is not a video")
    cases = [
        ([str(tmp_path / "missing.mp4")], "cannot read"),
        ([str(tmp_path / "empty")], "no images"),
        ([str(tmp_path / "*.png")], "no files match"),
        ([str(tmp_path / "bad.mp4")], "cannot open video"),
        ([str(video), "--overlay", str(tmp_path / "no" / "dir.mp4")], "cannot open overlay"),
        ([str(video), "--out", str(tmp_path / "no" / "dir.jsonl")], "cannot write"),
    ]
    for args, message in cases:
        assert message in _error(capsys, ["track", *args, *init], EXIT_IO), args


def test_a_file_that_is_not_a_video_gives_one_clean_line(tmp_path: Path) -> None:
    """FFmpeg's own "moov atom not found" came before the command's error (an audit)."""
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"this is not a video")
    env = {k: v for k, v in os.environ.items() if k != "OPENCV_FFMPEG_LOGLEVEL"}
    run = subprocess.run(
        [sys.executable, "-m", "efdm_cli", "track", str(bad), "--init-circle", CIRCLE, "-q"],
        capture_output=True, text=True, env=env, timeout=120, check=False,
    )  # fmt: skip
    assert run.returncode == EXIT_IO
    assert run.stderr == f"efdm track: error: cannot open video {bad}\n"


def test_a_reader_closing_the_pipe_stops_the_run_quietly(folder: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "efdm_cli", "track", str(folder), "--init-circle", CIRCLE,
         "--nodes", "600"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE,
    )  # fmt: skip
    assert proc.stdout is not None
    assert proc.stderr is not None
    assert json.loads(proc.stdout.readline())["frame"] == 0  # 12 records of 11 kB > a pipe
    proc.stdout.close()
    assert proc.wait(timeout=60) == 0
    assert proc.stderr.read() == b""
    proc.stderr.close()


def disc_box(i: int) -> str:
    """The disc's box on frame ``i`` in pixel edges, grown by 3 px (a rough box)."""
    cx, cy = disc_centre(i)
    return f"{cx - R - 3:g},{cy - R - 3:g},{cx + R + 4:g},{cy + R + 4:g}"


@pytest.mark.parametrize("snap", [True, False])
def test_a_box_snaps_onto_the_disc_unless_told_not_to(
    folder: Path, tmp_path: Path, snap: bool
) -> None:
    from engine.geometry import contour_to_mask, mask_iou

    out = tmp_path / "t.jsonl"
    argv = ["track", str(folder), "--init-box", disc_box(0), "-o", str(out), "-q"]
    assert main(argv if snap else [*argv, "--no-snap"]) == 0
    first = np.array(read_records(out.read_text())[0]["nodes"])
    truth = np.zeros((H, W), np.uint8)
    cx, cy = disc_centre(0)
    cv2.circle(truth, (round(cx), round(cy)), R, 255, -1)
    iou = mask_iou(contour_to_mask(first, (H, W)), truth)
    if snap:
        assert iou > 0.87  # the box became the disc's outline (give or take its 1 px rim)
    else:
        assert iou < 0.85  # the box itself: a square around the disc
        xs, ys = first[:, 0], first[:, 1]
        assert xs.min() == pytest.approx(cx - R - 3)
        assert ys.min() == pytest.approx(cy - R - 3)


def test_the_snap_reads_what_moved_between_the_first_two_frames(tmp_path: Path) -> None:
    """``--init-box`` snaps with the second frame (a still patch of the object's colours in
    the box goes); a one-frame input snaps from colour alone, as the library does."""
    from engine.geometry import contour_to_mask, mask_iou
    from engine.tracking.snap import snap
    from tests.engine.scenes import decoy_scene

    first, second, truth, patch = decoy_scene()
    for i, frame in enumerate((first, second, second)):
        assert cv2.imwrite(str(tmp_path / f"f{i}.png"), frame)
    ys, xs = np.nonzero(truth)
    box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
    argv = ["track", "--init-box", ",".join(map(str, box)), "-q"]
    out = tmp_path / "t.jsonl"
    assert main([*argv, str(tmp_path / "f*.png"), "-o", str(out)]) == 0
    records = read_records(out.read_text())
    assert len(records) == 3  # the frame read ahead is tracked once, in its turn
    shape = truth.shape
    found = contour_to_mask(np.array(records[0]["nodes"]), shape)
    assert mask_iou(found, snap(first, box, next_frame=second)) > 0.97
    assert mask_iou(found, truth) > 0.95
    assert (found[patch] > 0).mean() < 0.1
    one = tmp_path / "one.jsonl"
    assert main([*argv, str(tmp_path / "f0.png"), "-o", str(one)]) == 0
    alone = contour_to_mask(np.array(read_records(one.read_text())[0]["nodes"]), shape)
    assert mask_iou(alone, snap(first, box)) > 0.97
    assert mask_iou(alone, truth) < 0.95  # the patch kept


def test_a_loose_circle_snaps_when_asked(folder: Path, tmp_path: Path) -> None:
    from engine.geometry import contour_to_mask, mask_iou

    out = tmp_path / "t.jsonl"
    loose = f"40,60,{R + 10}"
    argv = ["track", str(folder / "frame_00[01].png"), "--init-circle", loose, "--snap"]
    assert main([*argv, "-o", str(out), "-q"]) == 0
    first = np.array(read_records(out.read_text())[0]["nodes"])
    truth = np.zeros((H, W), np.uint8)
    cv2.circle(truth, (40, 60), R, 255, -1)
    assert mask_iou(contour_to_mask(first, (H, W)), truth) > 0.85  # 0.35 for the circle given


def test_a_mask_in_several_pieces_tracks_each_and_warns_of_specks_left_out(
    folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mask = np.zeros((H, W), np.uint8)
    cv2.circle(mask, (40, 60), R, 255, -1)
    cv2.rectangle(mask, (120, 10), (139, 29), 255, -1)  # a second piece, 400 px
    mask[110:112, 150:152] = 255  # a speck, 4 px
    path = tmp_path / "pieces.png"
    assert cv2.imwrite(str(path), mask)
    out, masks = tmp_path / "t.jsonl", tmp_path / "masks"
    argv = ["track", str(folder / "frame_00[012].png"), "--init-mask", str(path), "-q"]
    assert main([*argv, "-o", str(out), "--masks-out", str(masks)]) == 0
    err = capsys.readouterr().err
    assert "3 separate pieces; 1 under --min-piece-area 100 px left out: 4 px" in err
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert all("nodes" not in r and len(r["contours"]) == 2 for r in records)
    first = records[0]["contours"]
    assert len(first[0]) > len(first[1])  # the larger piece first, more nodes
    written = cv2.imread(str(masks / "frame_000.png"), cv2.IMREAD_GRAYSCALE)
    assert written is not None
    assert written[20, 130] == 255  # the square is in the mask
    assert written[60, 40] == 255  # and the disc
    assert main([*argv, "--min-piece-area", "1000", "-o", str(out)]) == 0
    assert "2 under --min-piece-area 1000 px" in capsys.readouterr().err
    assert "nodes" in json.loads(out.read_text().splitlines()[0])  # one piece: as before


def test_a_box_snapped_onto_an_object_in_pieces_tracks_every_piece(tmp_path: Path) -> None:
    """Two dark discs in one box: the snap finds both, and both are tracked (as a mask in
    pieces is); with ``--min-piece-area`` above the smaller, only the larger."""
    from engine.geometry import contour_to_mask, mask_iou

    truth = np.zeros((H, W), np.uint8)
    cv2.circle(truth, (50, 60), R, 255, -1)
    cv2.circle(truth, (108, 60), R - 6, 255, -1)
    for i in range(3):
        frame = np.clip(200 + np.random.default_rng(i).normal(0, 4, (H, W, 3)), 0, 255)
        frame[truth > 0] = (40, 50, 60)
        assert cv2.imwrite(str(tmp_path / f"f{i}.png"), frame.astype(np.uint8))
    out = tmp_path / "t.jsonl"
    argv = ["track", str(tmp_path / "f*.png"), "--init-box", "26,36,127,85", "-o", str(out), "-q"]
    assert main(argv) == 0
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert len(records) == 3
    assert all("nodes" not in r for r in records)
    pieces = records[0]["contours"]
    assert len(pieces) == 2
    assert len(pieces[0]) == 128  # the larger disc keeps --nodes, the smaller its spacing
    found = np.zeros((H, W), np.uint8)
    for piece in pieces:
        found |= contour_to_mask(np.array(piece), (H, W))
    assert mask_iou(found, truth) > 0.85
    assert main([*argv, "--min-piece-area", "1000"]) == 0
    assert len(read_records(out.read_text())[0]["nodes"]) == 128
