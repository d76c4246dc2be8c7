"""Frame validation and repeatable OpenCV for :class:`engine.tracking.Tracker`."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["as_frame", "as_image", "check_prepared", "grey_of", "repeatable_opencv"]


@contextlib.contextmanager
def repeatable_opencv() -> Iterator[None]:
    """OpenCV without its IPP fast paths, for this thread, while tracking.

    Some IPP kernels round differently with memory alignment and thread count,
    so the same frames could track a little differently from run to run (and
    between the library and the service).  Costs about 7 % of a frame's time;
    the setting is thread-local and restored afterwards.
    """
    previous = cv2.ipp.useIPP()
    cv2.ipp.setUseIPP(False)
    try:
        yield
    finally:
        cv2.ipp.setUseIPP(previous)


def as_frame(frame: Any) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Validate a frame; return it as (BGR or grey image, grey image)."""
    image = as_image(frame)
    return image, grey_of(image)


def grey_of(image: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The grey version of an image as :func:`as_image` returns it (itself if grey)."""
    if image.ndim == 2:
        return image
    return np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY), dtype=np.uint8)


def as_image(frame: Any) -> NDArray[np.uint8]:
    """Validate a frame; return it as a contiguous BGR or grey image (no grey version made:
    a frame tracked downscaled needs only its working grid's)."""
    if not isinstance(frame, np.ndarray):
        raise ValueError(f"frame must be a numpy array; got {type(frame).__name__}")
    if frame.dtype != np.uint8:
        raise ValueError(f"frame must be uint8 (as OpenCV decodes images); got {frame.dtype}")
    if frame.size == 0:
        raise ValueError(f"frame is empty: shape {frame.shape}")
    if frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[..., 0]
    if frame.ndim == 2:
        return np.ascontiguousarray(frame)
    if frame.ndim == 3 and frame.shape[2] in (3, 4):
        return np.ascontiguousarray(frame[..., :3])
    raise ValueError(f"frame must be H x W grey or H x W x 3 BGR; got shape {frame.shape}")


def check_prepared(
    image: NDArray[np.uint8], grey: NDArray[np.uint8], covered: NDArray[np.bool_] | None
) -> None:
    """Check a frame as :func:`as_frame` returns it, and the pixels other objects cover.

    Raises
    ------
    ValueError
        If they are not uint8, ``grey`` is not H x W, ``image`` is not that H x W (x 3),
        or ``covered`` (when given) is not an H x W bool mask.
    """
    if (
        image.dtype != np.uint8
        or grey.dtype != np.uint8
        or grey.ndim != 2
        or image.shape[:2] != grey.shape
        or image.ndim not in (2, 3)
        or (image.ndim == 3 and image.shape[2] != 3)
    ):
        raise ValueError(
            "step_prepared takes a uint8 H x W (x 3) image and its H x W grey version; "
            f"got {image.dtype} {image.shape} and {grey.dtype} {grey.shape}"
        )
    if covered is not None and (covered.dtype != np.bool_ or covered.shape != grey.shape):
        raise ValueError(
            f"covered must be a bool mask of the frame's size {grey.shape}; "
            f"got {covered.dtype} {covered.shape}"
        )
