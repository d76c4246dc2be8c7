"""Frames in and overlay video out for ``efdm track``.

An input is a video file (anything :class:`cv2.VideoCapture` reads), a folder
of images (sorted by file name) or a glob pattern (sorted).  Frames come out
as H x W x 3 BGR ``uint8`` arrays.
"""

from __future__ import annotations

import glob
import math
import re
from collections.abc import Generator
from pathlib import Path
from types import TracebackType

import cv2
import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, EXIT_IO, CliError

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
        self, name: str, index: int, nodes: NDArray[np.float64], shape: tuple[int, int]
    ) -> None:
        """Write frame ``index`` (input ``name``) of size ``shape`` (height, width)."""
        from engine.geometry import contour_to_mask

        stem = Path(name).stem if self.named else f"{index:05d}"
        path = self.folder / f"{stem}.png"
        mask = (contour_to_mask(nodes, shape) > 0).astype(np.uint8) * 255
        if not cv2.imwrite(str(path), mask):
            raise CliError(f"cannot write {path}", EXIT_IO)


class OverlayWriter:
    """A video of the frames with the tracked contour drawn over them.

    Parameters
    ----------
    path : str
        Output file; written with the ``mp4v`` codec.
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

    def __init__(self, path: str, fps: float, size: tuple[int, int]) -> None:
        self.path, self.size = path, size
        fourcc = cv2.VideoWriter.fourcc(*"mp4v")
        self._writer = cv2.VideoWriter(path, fourcc, fps, size)
        if not self._writer.isOpened():
            self._writer.release()
            raise CliError(f"cannot open overlay video {path} for writing", EXIT_IO)
        self._thickness = max(1, round(min(size) / 240))

    def write(
        self, frame: Image, nodes: NDArray[np.float64], index: int, confidence: float
    ) -> None:
        """Draw the closed contour ``nodes`` and a caption on a copy of ``frame``; append it."""
        canvas = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if frame.ndim == 2 else frame.copy()
        if len(nodes) and np.isfinite(nodes).all():
            scaled = np.round(np.clip(nodes, -1e5, 1e5) * (1 << self.SHIFT)).astype(np.int32)
            cv2.polylines(
                canvas, [scaled.reshape(-1, 1, 2)], True, self.COLOR, self._thickness,
                cv2.LINE_AA, self.SHIFT,
            )  # fmt: skip
        text = f"{index}  conf {confidence:.2f}"
        org, font, scale = (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.4
        cv2.putText(canvas, text, org, font, scale, (0, 0, 0), 3, cv2.LINE_AA)
        cv2.putText(canvas, text, org, font, scale, (255, 255, 255), 1, cv2.LINE_AA)
        self._writer.write(canvas)

    def close(self) -> None:
        """Finish the file."""
        self._writer.release()

    def __enter__(self) -> OverlayWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
