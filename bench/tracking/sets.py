"""The benchmark's sets and the clips chosen from them.

- ``davis-train``: the thirty DAVIS-2016 training sequences (``../shared/data/davis2016-train``),
  the only ones any choice is tuned on, by cross-validation (:mod:`bench.tracking.cv`);
- ``davis-val``: the five validation sequences (``../shared/data/davis2016``), reported and
  never tuned on;
- ``synthetic``: the conditions of ``engine.testing.synthetic`` (480 x 640), each drawn with
  :attr:`Config.synthetic_seeds` seeds (clips ``"occluder"``, ``"occluder@1"``, ...).

A :class:`ClipSpec` names a clip without its frames, so that a worker process loads it itself.
A set whose data is absent is skipped with a note.
"""

from __future__ import annotations

import tempfile
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bench.common.data import (
    DAVIS_ROOT,
    DAVIS_TRAIN_ROOT,
    Clip,
    Frame,
    Mask,
    davis_names,
    load_davis,
    load_synthetic,
    select,
    synthetic_conditions,
    synthetic_name,
)
from bench.common.log import log
from bench.tracking.config import Config

DAVIS_ROOTS: dict[str, Path] = {"davis-train": DAVIS_TRAIN_ROOT, "davis-val": DAVIS_ROOT}
TITLES = {
    "davis-train": "DAVIS-2016 training sequences (480p; tuned on by cross-validation only)",
    "davis-val": "DAVIS-2016 validation sequences (480p; held out: reported, never tuned on)",
    "synthetic": "synthetic sequences (`engine.testing.synthetic`, 480 x 640; `name@k`: seed k)",
}


@dataclass(frozen=True, slots=True)
class ClipSpec:
    """One clip to track, named rather than loaded.

    Attributes
    ----------
    set : str
        ``davis-train``, ``davis-val`` or ``synthetic``.
    name : str
        Sequence or condition.
    frames : int or None
        DAVIS: the first frames only (None: all); synthetic: the sequence's length.
    resize : float
        DAVIS: the factor its frames and masks are resized by (1: as they are).
    grey : bool
        DAVIS: its frames turned grey (H x W).
    tint : bool
        DAVIS: its frames as a monochrome camera with a warm cast sends them
        (:func:`tinted_frame`).
    noise : float
        DAVIS: deviation (levels) of the Gaussian noise added to every channel of its
        frames, as a noisy sensor's (:func:`noisy_frame`; 0: none).
    stride : int
        DAVIS: every how many of its frames are kept, masks alike (1: all): the clip a
        camera at ``1/stride`` of the frame rate gives. ``frames`` counts before it.
    codec : str
        DAVIS: a lossy video codec its frames go through last (:func:`coded`; empty: none).
    """

    set: str
    name: str
    frames: int | None
    resize: float = 1.0
    grey: bool = False
    tint: bool = False
    noise: float = 0.0
    stride: int = 1
    codec: str = ""

    def load(self) -> Clip:
        """The clip's frames and masks (its ``source`` is the set)."""
        if self.set == "synthetic":
            clip = load_synthetic(self.name, self.frames or 0)
            return Clip(clip.name, self.set, clip.frames, clip.masks, clip.visible)
        clip = load_davis(self.name, self.frames, DAVIS_ROOTS[self.set], source=self.set)
        if self.stride > 1:
            clip = strided(clip, self.stride)
        if self.resize != 1.0:
            h, w = clip.frames[0].shape[:2]
            clip = resized(clip, (round(h * self.resize), round(w * self.resize)))
        if self.grey:
            frames = tuple(grey_frame(f) for f in clip.frames)
            clip = Clip(clip.name, clip.source, frames, clip.masks, clip.visible)
        if self.tint:
            frames = tuple(tinted_frame(f) for f in clip.frames)
            clip = Clip(clip.name, clip.source, frames, clip.masks, clip.visible)
        if self.noise > 0:
            seed = zlib.crc32(self.name.encode())
            frames = tuple(noisy_frame(f, self.noise, (seed, k)) for k, f in enumerate(clip.frames))
            clip = Clip(clip.name, clip.source, frames, clip.masks, clip.visible)
        if self.codec:
            clip = Clip(
                clip.name, clip.source, coded(clip.frames, self.codec), clip.masks, clip.visible
            )
        return clip


def strided(clip: Clip, stride: int) -> Clip:
    """``clip`` with every ``stride``-th frame and mask kept, the first among them."""
    return Clip(
        clip.name, clip.source, clip.frames[::stride], clip.masks[::stride], clip.visible[::stride]
    )


CODECS: dict[str, tuple[str, str]] = {"mp4v": ("mp4v", ".mp4"), "vp8": ("VP80", ".mkv")}
"""``--codec``'s choices: OpenCV's FOURCC and the container it writes. The encoders of
``opencv-python-headless``'s FFmpeg (no H.264 among them): MPEG-4 part 2 and VP8, each at
OpenCV's default quality (35-39 dB PSNR on DAVIS)."""
CODEC_FPS = 24
"""The frame rate the clip is written at: DAVIS's (rate control spends its bits by it)."""


def coded(frames: Sequence[Frame], codec: str) -> tuple[Frame, ...]:
    """``frames`` (BGR or grey) written as a video with ``codec`` (a key of :data:`CODECS`)
    by :class:`cv2.VideoWriter` and read back: a user's compressed video. The same frames on
    every run (the encoders are deterministic).

    Raises
    ------
    ValueError
        If ``codec`` is not one of :data:`CODECS`.
    RuntimeError
        If this OpenCV cannot write or read back that video.
    """
    if codec not in CODECS:
        raise ValueError(f"codec must be one of {', '.join(CODECS)}; got {codec!r}")
    fourcc, suffix = CODECS[codec]
    h, w = frames[0].shape[:2]
    grey = frames[0].ndim == 2
    out: list[Frame] = []
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / f"clip{suffix}")
        writer = cv2.VideoWriter(path, cv2.VideoWriter.fourcc(*fourcc), CODEC_FPS, (w, h))
        if not writer.isOpened():
            raise RuntimeError(f"this OpenCV cannot write {codec} video ({fourcc}, {suffix})")
        for frame in frames:
            writer.write(cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR) if grey else frame)
        writer.release()
        reader = cv2.VideoCapture(path)
        while True:
            ok, image = reader.read()
            if not ok:
                break
            out.append(np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY) if grey else image))
        reader.release()
    if len(out) != len(frames) or out[0].shape[:2] != (h, w):
        raise RuntimeError(f"{codec}: {len(frames)} frames written, {len(out)} read back")
    return tuple(out)


def grey_frame(frame: Frame) -> Frame:
    """A BGR frame in grey (H x W), as OpenCV converts it."""
    return np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)


SEPIA = ((0.80, 8.0), (0.92, 6.0), (1.0, 4.0))
"""A sepia tone's (gain, offset) of the grey level for the blue, green and red channels."""


def tinted_frame(frame: Frame) -> Frame:
    """A BGR frame as a monochrome camera with a warm cast sends it: its grey level in a
    sepia tone (:data:`SEPIA`), through the YUV 4:2:0 of a video codec (colour at half
    resolution), decoded to BGR."""
    level = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY).astype(np.float32)
    toned = np.dstack([gain * level + offset for gain, offset in SEPIA])
    image = np.asarray(np.clip(np.rint(toned), 0, 255), np.uint8)
    h, w = image.shape[:2]
    even = image[: h - h % 2, : w - w % 2]  # 4:2:0 takes even sides
    yuv = cv2.cvtColor(np.ascontiguousarray(even), cv2.COLOR_BGR2YUV_I420)
    image[: h - h % 2, : w - w % 2] = cv2.cvtColor(yuv, cv2.COLOR_YUV2BGR_I420)
    return image


def noisy_frame(frame: Frame, sigma: float, seed: tuple[int, int]) -> Frame:
    """``frame`` with independent Gaussian noise of ``sigma`` levels on every pixel and
    channel (rounded, clipped to 0-255), drawn from ``seed`` (the clip's and the frame's):
    the same noise on every run."""
    noise = np.random.default_rng(seed).normal(0.0, sigma, frame.shape)
    return np.asarray(np.clip(np.rint(frame + noise), 0, 255), np.uint8)


def resized(clip: Clip, shape: tuple[int, int]) -> Clip:
    """``clip`` with its frames and masks brought to ``shape`` (height, width): frames by
    bicubic interpolation up, pixel areas down, masks by the nearest pixel."""
    h, w = shape
    if clip.frames[0].shape[:2] == (h, w):
        return clip
    up = h > clip.frames[0].shape[0]
    how = cv2.INTER_CUBIC if up else cv2.INTER_AREA

    def frame(image: Frame) -> Frame:
        return np.asarray(cv2.resize(image, (w, h), interpolation=how), np.uint8)

    def mask(image: Mask) -> Mask:
        return np.asarray(cv2.resize(image, (w, h), interpolation=cv2.INTER_NEAREST), np.uint8)

    frames = tuple(frame(f) for f in clip.frames)
    masks = tuple(mask(m) for m in clip.masks)
    return Clip(clip.name, clip.source, frames, masks, clip.visible)


def davis_view(config: Config) -> list[str]:
    """How a run changed the DAVIS frames before tracking (for its run line; empty: not)."""
    notes = []
    if config.davis_resize != 1.0:
        notes.append(f"DAVIS frames and masks resized by {config.davis_resize:g}")
    if config.davis_grey:
        notes.append("DAVIS frames in grey")
    if config.davis_tint:
        notes.append("DAVIS frames in a sepia tone through YUV 4:2:0")
    if config.davis_noise > 0:
        notes.append(f"Gaussian noise of {config.davis_noise:g} levels on every DAVIS channel")
    if config.davis_stride > 1:
        notes.append(f"one DAVIS frame in {config.davis_stride} tracked and scored")
    if config.davis_codec:
        notes.append(f"DAVIS frames through {config.davis_codec} video (OpenCV's encoder)")
    return notes


def is_davis(set_name: str) -> bool:
    """Whether a set is made of DAVIS sequences."""
    return set_name in DAVIS_ROOTS


def available(set_name: str, seeds: int = 1) -> tuple[list[str], str | None]:
    """The clips of a set present on this machine (synthetic: each condition with ``seeds``
    seeds, seed by seed), or none and why."""
    if is_davis(set_name):
        root = DAVIS_ROOTS[set_name]
        found = davis_names(root)
        return found, None if found else f"{set_name}: no sequences found at {root}: skipped"
    try:
        conditions = synthetic_conditions()
    except (ImportError, AttributeError) as exc:
        why = f"{type(exc).__name__}: {exc}"
        return [], f"synthetic: engine.testing.synthetic unavailable ({why}): skipped"
    return [synthetic_name(c, seed) for seed in range(seeds) for c in conditions], None


def choose(
    config: Config, set_name: str, wanted: Sequence[str] | None
) -> tuple[list[ClipSpec], str | None]:
    """The clips of a set to run (``wanted`` among those present, else the configured count),
    or none and why."""
    names, why = available(set_name, config.synthetic_seeds)
    if why is not None:
        log(why)
        return [], why
    count = {
        "davis-train": config.train_count,
        "davis-val": config.val_count,
        "synthetic": config.synthetic_count,
    }[set_name]
    synthetic = set_name == "synthetic"
    frames = config.synthetic_length if synthetic else config.davis_frames
    resize = 1.0 if synthetic else config.davis_resize
    grey = not synthetic and config.davis_grey
    tint = not synthetic and config.davis_tint
    noise = 0.0 if synthetic else config.davis_noise
    stride = 1 if synthetic else config.davis_stride
    codec = "" if synthetic else config.davis_codec
    chosen = select(names, wanted, count)
    specs = [
        ClipSpec(set_name, name, frames, resize, grey, tint, noise, stride, codec)
        for name in chosen
    ]
    return specs, None


def is_partial(config: Config, set_name: str, specs: Sequence[ClipSpec]) -> bool:
    """Whether a set runs less than all of it (``--quick``, ``--sequences``, a frame limit)."""
    short = config.davis_frames is not None and is_davis(set_name)
    everything = available(set_name, config.synthetic_seeds)[0]
    return config.name == "quick" or short or len(specs) < len(everything)


def limits(config: Config, set_name: str) -> dict[str, int]:
    """Frames the slow skimage baseline tracks per clip of a set (empty: all)."""
    limit = config.skimage_synthetic if set_name == "synthetic" else config.skimage_davis
    return {} if limit is None else {"skimage": limit}
