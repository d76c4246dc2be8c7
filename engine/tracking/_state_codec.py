"""Compact, validated encodings of the tracker's arrays for its JSON state, and old states."""

from __future__ import annotations

import base64
import zlib
from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

HISTOGRAM_SIZES = (32, 4096)  # grey and BGR bins, see engine.tracking.appearance


def pack_histogram(values: NDArray[np.float64]) -> str:
    """Base64 of zlib-compressed little-endian float64: exact and small."""
    return base64.b64encode(zlib.compress(values.astype("<f8").tobytes())).decode("ascii")


def _inflate(text: str, limit: int) -> bytes:
    """Base64 then zlib, reading at most one byte beyond ``limit`` (a zip bomb stops there)."""
    return zlib.decompressobj().decompress(base64.b64decode(text, validate=True), limit + 1)


def unpack_histogram(text: str) -> NDArray[np.float64]:
    """Inverse of :func:`pack_histogram`; rejects anything that is not a histogram."""
    limit = max(HISTOGRAM_SIZES) * 8
    raw = _inflate(text, limit)
    if len(raw) > limit or raw == b"" or len(raw) % 8:
        raise ValueError("histogram has the wrong size")
    values = np.frombuffer(raw, dtype="<f8").astype(np.float64)
    if len(values) not in HISTOGRAM_SIZES:
        raise ValueError(f"histogram must have {' or '.join(map(str, HISTOGRAM_SIZES))} bins")
    if not np.isfinite(values).all() or (values < 0).any():
        raise ValueError("histogram values must be finite and >= 0")
    return values


def pack_counts(counts: NDArray[np.float32]) -> str:
    """Base64 of zlib-compressed little-endian float32 (per-window colour counts): exact, small."""
    return base64.b64encode(zlib.compress(counts.astype("<f4").tobytes())).decode("ascii")


def unpack_counts(text: str, rows: int, sizes: tuple[int, ...]) -> NDArray[np.float32]:
    """Inverse of :func:`pack_counts`: ``rows`` x one of ``sizes`` counts, finite and >= 0."""
    limit = rows * max(sizes) * 4
    raw = _inflate(text, limit)
    if len(raw) not in (rows * size * 4 for size in sizes):
        raise ValueError("local colour windows: counts of the wrong size")
    counts = np.frombuffer(raw, dtype="<f4").astype(np.float32).reshape(rows, -1)
    if not np.isfinite(counts).all() or (counts < 0).any():
        raise ValueError("local colour windows: counts must be finite and >= 0")
    return counts


def pack_image(image: NDArray[np.uint8]) -> str:
    """A single-channel uint8 image as base64 PNG (lossless)."""
    ok, png = cv2.imencode(".png", image)
    if not ok:
        raise ValueError("image does not encode as PNG")
    return base64.b64encode(png.tobytes()).decode("ascii")


def unpack_image(text: str) -> NDArray[np.uint8]:
    """Inverse of :func:`pack_image`."""
    data = np.frombuffer(base64.b64decode(text, validate=True), np.uint8)
    image = cv2.imdecode(data, cv2.IMREAD_GRAYSCALE) if data.size else None
    if image is None:
        raise ValueError("image does not decode")
    return np.asarray(image, dtype=np.uint8)


def count(value: Any) -> int:
    """A non-negative integer from a state, or ValueError."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise ValueError(f"expected a count; got {value!r}")
    return value


def factors(values: Any, count: int) -> NDArray[np.float64]:
    """``count`` numbers in [0, 1] from a state, or ValueError."""
    arr = np.asarray(values, dtype=np.float64)
    if arr.shape != (count,) or not np.isfinite(arr).all() or (arr < 0).any() or (arr > 1).any():
        raise ValueError(f"expected {count} numbers in [0, 1]")
    return arr


def from_version_1(state: Mapping[str, Any]) -> dict[str, Any]:
    """A version-1 state (the default stages' state at the top level) as version 2."""
    model, previous = state.get("model"), state.get("previous")
    stages = None
    if model is not None and previous is not None:
        stages = {
            "motion": {"kind": "flow-motion", "features": state.get("features")},
            "appearance": {
                "kind": "colour-histogram",
                "object": model["object"],
                "background": model["background"],
            },
            "cues": {"kind": "region-edge-cues", "memory": state.get("probability")},
        }
    return {
        "version": 2,
        "nodes": state["nodes"],
        "options": state["options"],
        "frame_index": state["frame_index"],
        "previous": previous if stages is not None else None,
        "stages": stages,
    }
