"""Service benchmark data: 480p JPEG frames as bytes, with the initial contour.

DAVIS-2016 frames are used as they are on disk (the JPEG files' bytes, so the
service and the in-process baseline decode exactly the same data).  Without
the DAVIS subset, ``engine.testing.synthetic`` sequences are encoded as JPEG instead.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bench.common.data import DAVIS_ROOT, davis_names, load_synthetic, read_image
from engine.geometry import mask_to_contour

NODES = 128
DAVIS_CLIPS = ("blackswan", "dog")
SYNTHETIC_CLIPS = ("plain", "clutter")
JPEG_QUALITY = 90


@dataclass(frozen=True, slots=True)
class JpegClip:
    """One sequence as encoded frames.

    Attributes
    ----------
    name : str
        Sequence name.
    source : str
        ``"davis"`` or ``"synthetic"``.
    frames : tuple of bytes
        JPEG files, in order.
    nodes : list of [x, y]
        Initial contour on the first frame (``NODES`` nodes, pixels).
    shape : tuple of int
        Frame height and width.
    """

    name: str
    source: str
    frames: tuple[bytes, ...]
    nodes: list[list[float]]
    shape: tuple[int, int]

    @property
    def mean_bytes(self) -> float:
        """Mean encoded frame size."""
        return float(np.mean([len(f) for f in self.frames]))


def _shape_of(data: bytes) -> tuple[int, int]:
    image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise OSError("a benchmark frame does not decode")
    return int(image.shape[0]), int(image.shape[1])


def load_davis_jpeg(name: str, limit: int | None, root: Path = DAVIS_ROOT) -> JpegClip:
    """The JPEG files of one DAVIS sequence and the contour of its first mask.

    Raises
    ------
    OSError
        If the files cannot be read.
    """
    paths = sorted((root / name / "frames").glob("*.jpg"))[:limit]
    masks = sorted((root / name / "masks").glob("*.png"))
    if not paths or not masks:
        raise OSError(f"DAVIS sequence {name}: no frames or masks")
    frames = tuple(p.read_bytes() for p in paths)
    mask = read_image(masks[0], cv2.IMREAD_GRAYSCALE)
    nodes = mask_to_contour(mask, NODES).tolist()
    return JpegClip(name, "davis", frames, nodes, _shape_of(frames[0]))


def encode(frame: np.ndarray[tuple[int, ...], np.dtype[np.uint8]]) -> bytes:
    """A frame as JPEG bytes (quality :data:`JPEG_QUALITY`)."""
    ok, data = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:
        raise ValueError("JPEG encoding failed")
    return bytes(data.tobytes())


def load_synthetic_jpeg(name: str, length: int) -> JpegClip:
    """One ``engine.testing.synthetic`` sequence (480 x 640), JPEG-encoded."""
    clip = load_synthetic(name, length)
    nodes = mask_to_contour(clip.masks[0], NODES).tolist()
    frames = tuple(encode(f) for f in clip.frames)
    return JpegClip(name, "synthetic", frames, nodes, clip.shape)


def load_clips(limit: int | None, synthetic_length: int) -> tuple[list[JpegClip], list[str]]:
    """The benchmark's clips and notes about where they came from.

    Parameters
    ----------
    limit : int or None
        Frames per DAVIS sequence (None: all).
    synthetic_length : int
        Frames per synthetic sequence, used when DAVIS is absent.
    """
    available = davis_names()
    wanted: Sequence[str] = [n for n in DAVIS_CLIPS if n in available]
    if wanted:
        clips = [load_davis_jpeg(name, limit) for name in wanted]
        return clips, [f"frames: DAVIS-2016 {', '.join(wanted)} (JPEG files as stored)"]
    note = (
        f"DAVIS-2016 {', '.join(DAVIS_CLIPS)} not found at {DAVIS_ROOT}: using "
        f"engine.testing.synthetic sequences {', '.join(SYNTHETIC_CLIPS)} (480 x 640, JPEG "
        f"quality {JPEG_QUALITY}) instead"
    )
    return [load_synthetic_jpeg(name, synthetic_length) for name in SYNTHETIC_CLIPS], [note]
