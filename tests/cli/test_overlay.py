"""efdm track --overlay: H.264 MP4 or VP9 WebM, as browsers play them (PyAV)."""

from __future__ import annotations

from pathlib import Path

import av
import cv2
import numpy as np
import pytest

from efdm_cli import main


def frames_folder(tmp_path: Path, size: tuple[int, int], count: int = 6) -> Path:
    folder = tmp_path / "frames"
    folder.mkdir()
    w, h = size
    for i in range(count):
        frame = np.full((h, w, 3), 170, np.uint8)
        cv2.circle(frame, (40 + 2 * i, 40), 15, (40, 40, 200), -1)
        assert cv2.imwrite(str(folder / f"{i:03d}.png"), frame)
    return folder


@pytest.mark.parametrize(
    ("name", "codec", "size", "coded"),
    [
        ("o.mp4", "h264", (120, 90), (120, 90)),
        ("o.webm", "vp9", (120, 90), (120, 90)),
        ("odd.mp4", "h264", (121, 91), (122, 92)),  # yuv420p: padded to even sides
    ],
)
def test_the_overlay_is_a_video_browsers_play(
    tmp_path: Path, name: str, codec: str, size: tuple[int, int], coded: tuple[int, int]
) -> None:
    folder = frames_folder(tmp_path, size)
    overlay = tmp_path / name
    argv = ["track", str(folder), "--init-circle", "40,40,15", "-q", "-o", str(tmp_path / "t")]
    assert main([*argv, "--overlay", str(overlay)]) == 0
    with av.open(str(overlay)) as video:
        stream = video.streams.video[0]
        assert stream.codec_context.name == codec
        assert stream.codec_context.pix_fmt == "yuv420p"
        assert (stream.codec_context.width, stream.codec_context.height) == coded
        assert float(stream.average_rate or 0) == pytest.approx(25.0)
        pictures = [f.to_ndarray(format="bgr24") for f in video.decode(stream)]
    assert len(pictures) == 6
    # the contour is drawn in green over the first frame's disc
    green = (pictures[0][..., 1] > 180) & (pictures[0][..., 2] < 120)
    assert green.sum() > 30
    if name.endswith(".mp4"):
        head = overlay.read_bytes()[:64]
        assert b"ftyp" in head
        assert overlay.read_bytes().find(b"moov") < overlay.read_bytes().find(b"mdat")  # faststart
