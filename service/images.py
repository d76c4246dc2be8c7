"""Decoding uploaded frames safely: size, type and pixel limits before decoding."""

from __future__ import annotations

import struct

import cv2
import numpy as np
from numpy.typing import NDArray

from service.domain_errors import BadImageError, ImageTooLargeError, UnsupportedImageTypeError
from service.image_types import SUPPORTED, sniff
from service.units import too_many_bytes, too_many_pixels


def dimensions(data: bytes, kind: str) -> tuple[int, int] | None:
    """(width, height) read from the header without decoding, or None."""
    try:
        if kind == "image/png" and data[12:16] == b"IHDR":
            w, h = struct.unpack(">II", data[16:24])
            return int(w), int(h)
        if kind == "image/jpeg":
            return _jpeg_dimensions(data)
        if kind == "image/webp":
            chunk = data[12:16]
            if chunk == b"VP8X":
                w = int.from_bytes(data[24:27], "little") + 1
                h = int.from_bytes(data[27:30], "little") + 1
                return w, h
            if chunk == b"VP8 ":
                w, h = struct.unpack("<HH", data[26:30])
                return w & 0x3FFF, h & 0x3FFF
            if chunk == b"VP8L":
                bits = int.from_bytes(data[21:25], "little")
                return (bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1
    except (struct.error, IndexError, ValueError):
        return None
    return None


def _jpeg_dimensions(data: bytes) -> tuple[int, int] | None:
    i = 2
    while i + 9 < len(data):
        if data[i] != 0xFF:
            return None
        marker = data[i + 1]
        if marker == 0xFF:  # fill byte before a marker (T.81 B.1.1.2)
            i += 1
            continue
        if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
            i += 2
            continue
        length = struct.unpack(">H", data[i + 2 : i + 4])[0]
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            h, w = struct.unpack(">HH", data[i + 5 : i + 9])
            return int(w), int(h)
        i += 2 + length
    return None


def decode_frame(
    data: bytes, media_type: str | None, *, max_bytes: int, max_pixels: int
) -> NDArray[np.uint8]:
    """Decode an uploaded JPEG, PNG or WebP into a BGR (or grey) uint8 frame.

    Raises
    ------
    ImageTooLargeError
        More bytes or pixels than allowed.
    UnsupportedImageTypeError
        Declared as a type other than JPEG, PNG, WebP (or octet-stream).
    BadImageError
        Empty, of another format, or not decodable.
    """
    if len(data) > max_bytes:
        raise ImageTooLargeError(too_many_bytes("image", len(data), max_bytes))
    if not data:
        raise BadImageError("empty image")
    declared = (media_type or "").split(";")[0].strip().lower()
    if declared and declared not in SUPPORTED | {"application/octet-stream"}:
        raise UnsupportedImageTypeError(f"unsupported image type {declared!r}")
    kind = sniff(data)
    if kind is None:
        raise BadImageError("not a JPEG, PNG or WebP image")
    size = dimensions(data, kind)
    if size is None:
        raise BadImageError(f"unreadable {kind} header")
    w, h = size
    if w * h > max_pixels:
        raise ImageTooLargeError(too_many_pixels(w, h, max_pixels))
    frame = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if frame is None or frame.size == 0:
        raise BadImageError(f"the {kind} image does not decode")
    if frame.dtype == np.uint16:  # 16-bit PNG: keep the high byte
        frame = (np.asarray(frame, dtype=np.uint16) >> 8).astype(np.uint8)
    elif frame.dtype != np.uint8:
        raise BadImageError("unsupported sample format")
    if frame.ndim == 3 and frame.shape[2] == 4:
        frame = cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR)
    return np.asarray(frame, dtype=np.uint8)
