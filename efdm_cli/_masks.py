"""Initial masks for ``efdm track --init-mask``: binary masks and label images, never photos.

A mask is read losslessly: a binary image (one non-zero value, e.g. 0/255),
or a label image with one object per label, either 8-bit grey (the label is
the grey value) or a palette PNG as DAVIS-2017 writes it (OpenCV expands the
palette to colours; the PASCAL VOC colour map that DAVIS uses gives each
colour back its label).  Anything else, a JPEG or an image of many colours,
is a photo or a mask saved lossily, and is refused with a message rather
than thresholded silently.  Coordinates are ``[x, y]`` pixels.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["MAX_LABELS", "MaskError", "labels_of", "object_mask", "voc_colours"]

MAX_LABELS = 64
"""More distinct values than this is no label image: a photo, or a mask blurred
by resizing or lossy compression (DAVIS-2017 has at most a handful of objects)."""
JPEG_MAGIC = b"\xff\xd8\xff"


class MaskError(ValueError):
    """The file is not a usable mask; the message says why and what to give instead."""


def voc_colours(count: int = 256) -> NDArray[np.uint8]:
    """The PASCAL VOC colour map (RGB) of DAVIS-2017's palette PNGs: row ``k`` is label ``k``."""
    colours = np.zeros((count, 3), np.uint8)
    for k in range(count):
        value, r, g, b = k, 0, 0, 0
        for bit in range(8):
            r |= ((value >> 0) & 1) << (7 - bit)
            g |= ((value >> 1) & 1) << (7 - bit)
            b |= ((value >> 2) & 1) << (7 - bit)
            value >>= 3
        colours[k] = (r, g, b)
    return colours


def labels_of(image: NDArray[np.uint8], name: str) -> NDArray[np.int64]:
    """Per pixel label (0 = background) of a mask image as OpenCV reads it (BGR or grey).

    Raises
    ------
    MaskError
        Too many distinct values, or colours of no label palette.
    """
    if image.ndim == 3 and image.shape[2] >= 3:
        bgr = image[..., :3]
        if (bgr == bgr[..., :1]).all():  # a grey image stored as colour
            image = bgr[..., 0]
        else:
            flat = bgr.reshape(-1, 3)
            colours, inverse = np.unique(flat, axis=0, return_inverse=True)
            _check_count(len(colours), name)
            table = {tuple(int(v) for v in c[::-1]): k for k, c in enumerate(voc_colours())}
            codes = [table.get(tuple(int(v) for v in c)) for c in colours]
            if any(code is None for code in codes):
                if len(colours) == 2 and (colours[0] == 0).all():  # black and one colour
                    codes = [0, 1]
                else:
                    raise MaskError(
                        f"{name} has {len(colours)} colours that are not a label palette: "
                        "give a binary mask or a label image (8-bit grey, or a palette PNG)"
                    )
            return np.asarray(codes, np.int64)[inverse.ravel()].reshape(bgr.shape[:2])
    grey = image if image.ndim == 2 else image[..., 0]
    _check_count(len(np.unique(grey)), name)
    return grey.astype(np.int64)


def _check_count(count: int, name: str) -> None:
    if count > MAX_LABELS + 1:
        raise MaskError(
            f"{name} has {count} distinct values, a photo rather than a mask (at most "
            f"{MAX_LABELS} labels): give a binary mask or a label image, saved losslessly (PNG)"
        )


def object_mask(
    data: bytes, image: NDArray[np.uint8], name: str, label: int | None
) -> NDArray[np.bool_]:
    """The pixels of the object to track: all non-zero ones, or those of ``label``.

    Parameters
    ----------
    data : bytes
        The file's bytes (a JPEG is refused by its signature, whatever its name).
    image : numpy.ndarray
        The file as OpenCV reads it unchanged.
    name : str
        The file's name, for messages.
    label : int, optional
        Which label of a label image; needed when it has more than one.

    Raises
    ------
    MaskError
        A JPEG, a photo, several labels and no ``label``, or a ``label`` not in it.
    """
    if data[:3] == JPEG_MAGIC:
        raise MaskError(
            f"{name} is a JPEG: a mask must be lossless (PNG), JPEG smears its edges "
            "into many grey levels"
        )
    labels = labels_of(image, name)
    present = [int(v) for v in np.unique(labels) if v != 0]
    if label is not None:
        if label not in present:
            raise MaskError(f"{name} has no label {label}; its labels are {_listed(present)}")
        return np.asarray(labels == label)
    if len(present) > 1:
        raise MaskError(
            f"{name} is a label image of {len(present)} objects ({_listed(present)}): "
            "choose one with --label"
        )
    return np.asarray(labels != 0)


def _listed(values: list[int]) -> str:
    return ", ".join(map(str, values)) if values else "none"
