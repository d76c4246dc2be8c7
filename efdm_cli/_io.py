"""Frames in and overlay video out for ``efdm track``.

An input is a video file (anything :class:`cv2.VideoCapture` reads), a folder
of images (sorted by file name) or a glob pattern (sorted).  Frames come out
as H x W x 3 BGR ``uint8`` arrays.
"""

from __future__ import annotations

import glob
import math
import os
import re
from collections.abc import Generator
from fractions import Fraction
from pathlib import Path
from types import TracebackType
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError

# FFmpeg's own lines ("moov atom not found") before the command's clean error: quiet
# unless the user asks for them (read when OpenCV first opens a video)
os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")

__all__ = [
    "DEFAULT_FPS",
    "IMAGE_SUFFIXES",
    "FrameSource",
    "ImageFrames",
    "OverlayWriter",
    "VideoFrames",
    "check_size",
    "open_frames",
    "read_image",
]

Image = NDArray[np.uint8]

IMAGE_SUFFIXES = frozenset({".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff", ".webp"})
DEFAULT_FPS = 25.0  # the overlay's frame rate when the input has none (images)
_GLOB_MAGIC = re.compile(r"[*?\[]")


def read_image(path: str, flags: int = cv2.IMREAD_COLOR) -> Image:
    """Decode the image file at ``path`` (``cv2.imdecode`` flags).

    Raises
    ------
    CliError
        :data:`EXIT_IO` naming the file when it cannot be read or decoded.
    """
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise CliError(f"cannot read {path}: {exc.strerror or exc}", EXIT_IO) from None
    image = cv2.imdecode(data, flags) if data.size else None
    if image is None:
        raise CliError(f"cannot decode image {path}", EXIT_IO)
    return np.asarray(image)


class FrameSource:
    """Frames of one input, read lazily.

    Attributes
    ----------
    description : str
        The input as given, for messages.
    total : int or None
        Number of frames when known in advance (for a video, as reported
        by its container, which may be approximate).
    fps : float
        Frame rate for an overlay video (the input's, else :data:`DEFAULT_FPS`).
    """

    description: str
    total: int | None
    fps: float

    def frames(self) -> Generator[tuple[str, Image], None, None]:
        """Yield ``(name, frame)``; ``name`` identifies the frame in messages."""
        raise NotImplementedError


class ImageFrames(FrameSource):
    """A sorted list of image files, one frame each."""

    def __init__(self, description: str, paths: list[str]) -> None:
        self.description, self.paths = description, paths
        self.total, self.fps = len(paths), DEFAULT_FPS

    def frames(self) -> Generator[tuple[str, Image], None, None]:
        """Yield ``(path, frame)``; a file that fails to decode raises :class:`CliError`."""
        for path in self.paths:
            yield path, read_image(path)


class VideoFrames(FrameSource):
    """A video file read with :class:`cv2.VideoCapture`."""

    def __init__(self, path: str) -> None:
        self.description = path
        capture = cv2.VideoCapture(path)
        try:
            if not capture.isOpened():
                raise CliError(f"cannot open video {path}", EXIT_IO)
            count = capture.get(cv2.CAP_PROP_FRAME_COUNT)
            fps = capture.get(cv2.CAP_PROP_FPS)
        finally:
            capture.release()
        self.total = int(count) if math.isfinite(count) and count >= 1 else None
        self.fps = float(fps) if math.isfinite(fps) and 0 < fps <= 1000 else DEFAULT_FPS

    def frames(self) -> Generator[tuple[str, Image], None, None]:
        """Yield ``(path, frame)`` until the video ends."""
        capture = cv2.VideoCapture(self.description)
        try:
            while True:
                ok, frame = capture.read()
                if not ok or frame is None:
                    return
                yield self.description, np.asarray(frame)
        finally:
            capture.release()


def open_frames(source: str) -> FrameSource:
    """The frames of ``source``: a folder of images, a video file or a glob pattern.

    Raises
    ------
    CliError
        :data:`EXIT_IO` when ``source`` does not exist, matches nothing, holds
        no images or is not a readable video.
    """
    path = Path(source)
    if path.is_dir():
        files = sorted(
            (p for p in path.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES and p.is_file()),
            key=lambda p: p.name,
        )
        if not files:
            suffixes = "/".join(sorted(s[1:] for s in IMAGE_SUFFIXES))
            raise CliError(f"no images ({suffixes}) in folder {source}", EXIT_IO)
        return ImageFrames(source, [str(p) for p in files])
    if path.is_file():
        return VideoFrames(source)
    if _GLOB_MAGIC.search(source):
        matches = sorted(m for m in glob.glob(source) if Path(m).is_file())
        if not matches:
            raise CliError(f"no files match {source}", EXIT_IO)
        return ImageFrames(source, matches)
    raise CliError(f"cannot read {source}: no such file or directory", EXIT_IO)


def check_size(name: str, index: int, frame: Image, size: tuple[int, int]) -> None:
    """Raise :class:`CliError` (invalid data) if ``frame`` is not ``size`` = (W, H)."""
    height, width = frame.shape[:2]
    if (width, height) != size:
        raise CliError(
            f"frame {index} ({name}) is {width} x {height}, "
            f"but the first frame is {size[0]} x {size[1]}",
            EXIT_INVALID,
        )


class MaskWriter:
    """Each frame's contour as a binary PNG mask (0/255) in a folder.

    Parameters
    ----------
    folder : str
        Created if missing.
    named : bool
        Name each mask after its input image (``frames/00012.jpg`` ->
        ``00012.png``); else after the frame's index, five digits as DAVIS.

    Raises
    ------
    CliError
        :data:`EXIT_IO` when the folder or a mask cannot be written.
    """

    def __init__(self, folder: str, *, named: bool) -> None:
        self.folder, self.named = Path(folder), named
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CliError(f"cannot create {folder}: {exc.strerror or exc}", EXIT_IO) from None

    def write(
        self,
        name: str,
        index: int,
        nodes: NDArray[np.float64] | list[NDArray[np.float64]],
        shape: tuple[int, int],
    ) -> None:
        """Write frame ``index`` (input ``name``) of size ``shape`` (height, width): the
        pixels inside the contour ``nodes`` (or inside any of a list of contours)."""
        from engine.geometry import contour_to_mask

        stem = Path(name).stem if self.named else f"{index:05d}"
        path = self.folder / f"{stem}.png"
        inside = np.zeros(shape, np.uint8)
        for piece in nodes if isinstance(nodes, list) else [nodes]:
            inside |= contour_to_mask(piece, shape)
        mask = (inside > 0).astype(np.uint8) * 255
        if not cv2.imwrite(str(path), mask):
            raise CliError(f"cannot write {path}", EXIT_IO)

    def write_labels(
        self, name: str, index: int, objects: list[Any], shape: tuple[int, int]
    ) -> None:
        """Write frame ``index`` as a label image: each pixel the id of its object (0: none),
        8-bit; where objects overlap, the one in front's
        (:func:`engine.tracking.label_mask`)."""
        from engine.tracking.objects import label_mask

        stem = Path(name).stem if self.named else f"{index:05d}"
        path = self.folder / f"{stem}.png"
        labels = label_mask(objects, shape)
        ids = np.array([0, *(int(o.id) for o in objects)], np.uint8)
        if not cv2.imwrite(str(path), ids[labels]):
            raise CliError(f"cannot write {path}", EXIT_IO)


class OverlayWriter:
    """A video of the frames with the tracked contour drawn over them, one browsers play.

    Encoded by PyAV (FFmpeg): H.264 (``libx264``, yuv420p, the index at the
    front of the file) for ``.mp4``/``.mov``/``.mkv`` and anything else, VP9
    (``libvpx-vp9``) for ``.webm``.  An odd width or height is padded by one
    black pixel (yuv420p needs even sides).

    Parameters
    ----------
    path : str
        Output file.
    fps : float
        Frame rate.
    size : tuple of int
        ``(width, height)`` of every frame.

    Raises
    ------
    CliError
        :data:`EXIT_IO` when the file cannot be opened for writing.
    """

    COLOR = (0, 255, 0)  # BGR
    SHIFT = 4  # sub-pixel bits for cv2.polylines
    H264_OPTIONS: ClassVar[dict[str, str]] = {"crf": "23", "preset": "veryfast"}
    """Visually clean at a few hundred kB per minute of 480p, faster than real time."""
    VP9_OPTIONS: ClassVar[dict[str, str]] = {
        "crf": "32",
        "b": "0",
        "deadline": "realtime",
        "cpu-used": "8",
    }
    """Constant quality, the encoder's fastest setting."""

    def __init__(self, path: str, fps: float, size: tuple[int, int]) -> None:
        import av

        self.path, self.size = path, size
        webm = Path(path).suffix.lower() == ".webm"
        options = {} if webm else {"movflags": "+faststart"}
        try:
            container = av.open(path, mode="w", options=options)
        except (OSError, av.FFmpegError, ValueError) as exc:
            raise CliError(
                f"cannot open overlay video {path} for writing: {exc}", EXIT_IO
            ) from None
        rate = Fraction(fps).limit_denominator(1001) if fps > 0 else Fraction(DEFAULT_FPS)
        codec = "libvpx-vp9" if webm else "libx264"
        self._container: av.container.OutputContainer | None = container
        stream = container.add_stream(codec, rate=rate)
        assert isinstance(stream, av.video.stream.VideoStream)
        self._stream = stream
        width, height = size
        self._stream.width, self._stream.height = width + width % 2, height + height % 2
        self._stream.pix_fmt = "yuv420p"
        self._stream.options = dict(self.VP9_OPTIONS if webm else self.H264_OPTIONS)
        try:
            container.start_encoding()  # opens the file and writes its header now
        except (OSError, av.FFmpegError, ValueError) as exc:
            container.close()
            raise CliError(
                f"cannot open overlay video {path} for writing: {exc}", EXIT_IO
            ) from None
        self._thickness = max(1, round(min(size) / 240))

    def write(
        self,
        frame: Image,
        nodes: NDArray[np.float64] | list[NDArray[np.float64]],
        index: int,
        confidence: float,
    ) -> None:
        """Draw the closed contour ``nodes`` (or each of a list of contours) and a caption
        on a copy of ``frame``; append it."""
        canvas = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()
        for piece in nodes if isinstance(nodes, list) else [nodes]:
            if not (len(piece) and np.isfinite(piece).all()):
                continue
            scaled = np.round(np.clip(piece, -1e5, 1e5) * (1 << self.SHIFT)).astype(np.int32)
            cv2.polylines(
                canvas, [scaled.reshape(-1, 1, 2)], True, self.COLOR, self._thickness,
                cv2.LINE_AA, self.SHIFT,
            )  # fmt: skip
        text = f"{index}  conf {confidence:.2f}"
        org, font, scale = (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4
        cv2.putText(canvas, text, org, font, scale, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(canvas, text, org, font, scale, (255, 255, 255), 1, cv2.LINE_AA)
        pad_w, pad_h = self._stream.width - canvas.shape[1], self._stream.height - canvas.shape[0]
        if pad_w or pad_h:
            canvas = cv2.copyMakeBorder(canvas, 0, pad_h, 0, pad_w, cv2.BORDER_CONSTANT)
        import av

        pixels = np.ascontiguousarray(canvas, dtype=np.uint8)
        picture = av.VideoFrame.from_ndarray(pixels, format="bgr24")
        assert self._container is not None, "the overlay is closed"
        for packet in self._stream.encode(picture):
            self._container.mux(packet)

    def close(self) -> None:
        """Flush the encoder and finish the file (its index written)."""
        if self._container is None:
            return
        try:
            for packet in self._stream.encode(None):
                self._container.mux(packet)
        finally:
            self._container.close()
            self._container = None

    def __enter__(self) -> OverlayWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
