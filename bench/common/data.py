"""The sequences the benchmarks run on: DAVIS-2016 (training and validation) and synthetic ones.

Both give :class:`Clip` objects: frames (H x W x 3 BGR uint8) with one
ground-truth mask each (H x W uint8, 0 / 255); the tracking benchmark runs on
them, the service benchmark sends them as JPEG.  ``engine.testing.synthetic``
is imported lazily, so the DAVIS part runs while it is missing.
"""

from __future__ import annotations

import importlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from bench.common import REPO

Frame = NDArray[np.uint8]
Mask = NDArray[np.uint8]

DAVIS_ROOT = REPO.parent / "shared" / "data" / "davis2016"
"""The five DAVIS-2016 validation sequences beside the repository (``../shared/data/davis2016``):
a held-out check, reported and never tuned on."""
DAVIS_TRAIN_ROOT = REPO.parent / "shared" / "data" / "davis2016-train"
"""The thirty DAVIS-2016 training sequences (``../shared/data/davis2016-train``): the set to
tune on, by cross-validation."""
DAVIS_ORDER = ("blackswan", "car-shadow", "dog", "soapbox", "breakdance")
"""The order of the DAVIS README's tables; other sequences follow alphabetically."""


@dataclass(frozen=True, slots=True)
class Clip:
    """One evaluation sequence.

    Attributes
    ----------
    name : str
        Sequence (DAVIS) or condition (synthetic) name.
    source : str
        ``"davis"`` (or the DAVIS set it belongs to) or ``"synthetic"``.
    frames : tuple of numpy.ndarray
        H x W x 3 BGR uint8 frames.
    masks : tuple of numpy.ndarray
        H x W uint8 ground truth, 0 = background, 255 = object.
    visible : tuple of bool
        Whether the object can be seen in each frame (False: entirely hidden, as in the
        synthetic ``"hidden"``; the mask then is where it is).  Left out or empty when
        constructing: every frame, so it is always one flag per frame once constructed.

    Raises
    ------
    ValueError
        If ``visible`` is given with another length than ``frames``.
    """

    name: str
    source: str
    frames: tuple[Frame, ...]
    masks: tuple[Mask, ...]
    visible: tuple[bool, ...] = ()

    def __post_init__(self) -> None:
        if not self.visible:
            object.__setattr__(self, "visible", (True,) * len(self.frames))
        elif len(self.visible) != len(self.frames):
            raise ValueError(
                f"{self.name}: {len(self.visible)} visibility flags for {len(self.frames)} frames"
            )

    @property
    def shape(self) -> tuple[int, int]:
        """Frame height and width."""
        height, width = self.frames[0].shape[:2]
        return int(height), int(width)


def davis_names(root: Path = DAVIS_ROOT) -> list[str]:
    """Sequences present under ``root`` (each with ``frames/`` and ``masks/``), README order."""
    if not root.is_dir():
        return []
    found = {p.name for p in root.iterdir() if (p / "frames").is_dir() and (p / "masks").is_dir()}
    known = [name for name in DAVIS_ORDER if name in found]
    return known + sorted(found - set(known))


def read_image(path: Path, flags: int) -> NDArray[np.uint8]:
    """``cv2.imread`` that raises instead of returning None."""
    image = cv2.imread(str(path), flags)
    if image is None:
        raise OSError(f"cannot read image {path}")
    return np.asarray(image, dtype=np.uint8)


def load_davis(
    name: str, limit: int | None = None, root: Path = DAVIS_ROOT, source: str = "davis"
) -> Clip:
    """Frames and masks of one DAVIS sequence, optionally only the first ``limit``.

    ``source`` labels the clip (e.g. the set it belongs to).

    Raises
    ------
    OSError
        If a file cannot be read or frames and masks do not pair up.
    """
    frame_paths = sorted((root / name / "frames").glob("*.jpg"))[:limit]
    mask_paths = sorted((root / name / "masks").glob("*.png"))[:limit]
    if not frame_paths or [p.stem for p in frame_paths] != [p.stem for p in mask_paths]:
        raise OSError(f"DAVIS sequence {name}: frames and masks do not pair up")
    frames = tuple(read_image(p, cv2.IMREAD_COLOR) for p in frame_paths)
    masks = tuple(read_image(p, cv2.IMREAD_GRAYSCALE) for p in mask_paths)
    return Clip(name, source, frames, masks)


def synthetic_module() -> Any:
    """``engine.testing.synthetic``, imported on first use (ImportError while it is missing)."""
    return importlib.import_module("engine.testing.synthetic")


def synthetic_conditions() -> tuple[str, ...]:
    """``engine.testing.synthetic.CONDITIONS``."""
    return tuple(str(c) for c in synthetic_module().CONDITIONS)


SEED_MARK = "@"
"""A synthetic clip ``"occluder@2"`` is condition ``"occluder"`` drawn with seed 2 (plain
``"occluder"``: seed 0)."""


def synthetic_name(condition: str, seed: int) -> str:
    """The clip name of a condition drawn with a seed (the bare condition for seed 0)."""
    return condition if seed == 0 else f"{condition}{SEED_MARK}{seed}"


def synthetic_condition(name: str) -> tuple[str, int]:
    """``(condition, seed)`` of a synthetic clip name (:func:`synthetic_name`)."""
    condition, _, seed = name.partition(SEED_MARK)
    return condition, int(seed) if seed else 0


def load_synthetic(name: str, length: int) -> Clip:
    """One synthetic sequence (480 x 640; ``name`` as :func:`synthetic_name`) as a
    :class:`Clip`, with the frames where the object is hidden (its ``visible`` flags; all
    visible if the module has none)."""
    condition, seed = synthetic_condition(name)
    sequence = synthetic_module().make_sequence(
        condition, seed=seed, length=length, size=(480, 640)
    )
    frames = tuple(as_frame(f) for f in sequence.frames)
    masks = tuple(np.asarray(m, dtype=np.uint8) for m in sequence.masks)
    if len(frames) != len(masks) or not frames:
        raise ValueError(f"synthetic {name}: {len(frames)} frames but {len(masks)} masks")
    visible = tuple(bool(v) for v in getattr(sequence, "visible", ()))
    return Clip(name, "synthetic", frames, masks, visible)


def as_frame(frame: Any) -> Frame:
    """A frame as H x W x 3 BGR uint8 (grey frames are expanded)."""
    arr = np.asarray(frame, dtype=np.uint8)
    if arr.ndim == 2:
        arr = np.asarray(cv2.cvtColor(arr, cv2.COLOR_GRAY2BGR), dtype=np.uint8)
    return arr


def select(available: Sequence[str], wanted: Sequence[str] | None, count: int | None) -> list[str]:
    """Names to run: ``wanted`` (those available, in order) or else the first ``count``."""
    if wanted is not None:
        return [name for name in wanted if name in available]
    return list(available[:count])
