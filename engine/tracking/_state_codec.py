"""Compact, validated encodings of the tracker's arrays for its JSON state, and old states."""

from __future__ import annotations

import base64
import json
import zlib
from collections.abc import Mapping
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

HISTOGRAM_SIZES = (32, 4096, 32768)  # grey, BGR at 16 (old states) and 32 levels: see appearance


HISTOGRAM_DTYPES = ("float64", "float16")
"""How a state's histograms are stored: exactly, or (compact states) to three digits."""


def pack_histogram(values: NDArray[np.float64], dtype: str = "float64") -> str:
    """Base64 of zlib-compressed little-endian ``dtype`` values (float64: exact)."""
    stored = values.astype(np.dtype(dtype).newbyteorder("<"))
    return base64.b64encode(zlib.compress(stored.tobytes())).decode("ascii")


def _inflate(text: str, limit: int) -> bytes:
    """Base64 then zlib, reading at most one byte beyond ``limit`` (a zip bomb stops there)."""
    return zlib.decompressobj().decompress(base64.b64decode(text, validate=True), limit + 1)


def unpack_histogram(text: str, dtype: str = "float64") -> NDArray[np.float64]:
    """Inverse of :func:`pack_histogram`; rejects anything that is not a histogram."""
    if dtype not in HISTOGRAM_DTYPES:
        raise ValueError(f"histograms are stored as {' or '.join(HISTOGRAM_DTYPES)}, not {dtype!r}")
    stored = np.dtype(dtype).newbyteorder("<")
    limit = max(HISTOGRAM_SIZES) * stored.itemsize
    raw = _inflate(text, limit)
    if len(raw) > limit or raw == b"" or len(raw) % stored.itemsize:
        raise ValueError("histogram has the wrong size")
    values = np.frombuffer(raw, dtype=stored).astype(np.float64)
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


def pack_raw(values: NDArray[Any]) -> str:
    """Base64 of zlib-compressed bytes of an array (its dtype and shape are the reader's)."""
    return base64.b64encode(zlib.compress(np.ascontiguousarray(values).tobytes())).decode("ascii")


def unpack_raw(text: str, dtype: np.dtype[Any] | type, size: int | None) -> NDArray[Any]:
    """Inverse of :func:`pack_raw`: a 1-D array of ``dtype``, of ``size`` items (None: any
    number up to 2^22); ValueError otherwise."""
    kind = np.dtype(dtype)
    limit = (1 << 22 if size is None else size) * kind.itemsize
    raw = _inflate(text, limit)
    if len(raw) > limit or len(raw) % kind.itemsize or (size is not None and len(raw) != limit):
        raise ValueError("packed array has the wrong size")
    return np.frombuffer(raw, dtype=kind).copy()


def pack_image(image: NDArray[np.uint8], *, quality: int | None = None) -> str:
    """A uint8 image, grey (H x W) or BGR (H x W x 3), as base64 PNG text (lossless), or
    given a JPEG ``quality`` (1-100) as base64 JPEG text (lossy, several times smaller)."""
    if quality is not None:
        return _jpeg(image, quality)
    ok, png = cv2.imencode(".png", image)
    if not ok:
        raise ValueError("image does not encode as PNG")
    return base64.b64encode(png.tobytes()).decode("ascii")


def unpack_image(text: str, *, colour: bool = False) -> NDArray[np.uint8]:
    """Inverse of :func:`pack_image` (PNG or JPEG): a grey image, or with ``colour`` the
    image as it was packed (grey or BGR); ValueError if ``text`` is not such an image."""
    data = np.frombuffer(base64.b64decode(text, validate=True), np.uint8)
    flag = cv2.IMREAD_UNCHANGED if colour else cv2.IMREAD_GRAYSCALE
    image = cv2.imdecode(data, flag) if data.size else None
    if image is None or image.dtype != np.uint8 or image.ndim not in (2, 3):
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


COMPACT_MARGIN = 64
"""Pixels of the previous frame kept sharp around the contour in a compact state: the
motion stage's context (:data:`engine.tracking.motion.CONTEXT`), which also covers the
cue maps' region (twice the search radius) for objects moving up to 36 pixels a frame."""
COMPACT_QUALITIES = (90, 80, 70, 60, 50, 40, 30, 20)
"""JPEG qualities tried in turn for the kept region (stored at half resolution) until
the frame fits its byte budget: at 90, grey levels within a few of the original."""
CONTEXT_SCALE = 4
"""The rest of the frame is kept at a quarter of its resolution (a few kB)."""
CONTEXT_QUALITY = 50
"""JPEG quality of that reduced frame: only coarse context is read there."""
MAX_SIDE = 1 << 15
"""Largest frame side a compact state may declare (OpenCV's own image limit)."""


def _jpeg(image: NDArray[np.uint8], quality: int) -> str:
    ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError("image does not encode as JPEG")
    return base64.b64encode(data.tobytes()).decode("ascii")


def _box(shape: tuple[int, int], nodes: NDArray[np.float64], margin: int) -> tuple[int, ...]:
    """``(x0, y0, x1, y1)`` of the nodes' box grown by ``margin``, clipped, even-sided."""
    h, w = shape
    x0, y0 = (max(int(v) - margin, 0) for v in np.floor(nodes.min(axis=0)))
    x1, y1 = (int(v) + margin + 1 for v in np.ceil(nodes.max(axis=0)))
    x0, y0 = min(x0, w - 2), min(y0, h - 2)
    x1, y1 = min(max(x1, x0 + 2), w), min(max(y1, y0 + 2), h)
    return x0, y0, x0 + (x1 - x0) // 2 * 2, y0 + (y1 - y0) // 2 * 2


def pack_compact_frame(
    grey: NDArray[np.uint8], nodes: NDArray[np.float64], budget: int
) -> dict[str, Any]:
    """A grey frame in a few tens of kB: sharp(ish) around ``nodes``, coarse elsewhere.

    The region of :data:`COMPACT_MARGIN` pixels around the nodes' box is kept at half
    resolution, JPEG of the best of :data:`COMPACT_QUALITIES` whose encoding keeps
    the whole within ``budget`` characters (else the lowest), the whole frame at a
    quarter (:data:`CONTEXT_SCALE`, JPEG :data:`CONTEXT_QUALITY`);
    :func:`unpack_compact_frame` gives a full-size approximation.  Lossy: a tracker
    resumed from it tracks its next frame slightly differently (frames of at least
    2 x 2 pixels).
    """
    h, w = grey.shape
    x0, y0, x1, y1 = _box((h, w), nodes, COMPACT_MARGIN)
    half = ((x1 - x0) // 2, (y1 - y0) // 2)
    detail = cv2.resize(grey[y0:y1, x0:x1], half, interpolation=cv2.INTER_AREA)
    small = (max(w // CONTEXT_SCALE, 1), max(h // CONTEXT_SCALE, 1))
    context = _jpeg(
        np.asarray(cv2.resize(grey, small, interpolation=cv2.INTER_AREA)), CONTEXT_QUALITY
    )
    packed = {"shape": [h, w], "box": [x0, y0, x1, y1], "detail": "", "context": context}
    room = budget - len(json.dumps(packed))
    for quality in COMPACT_QUALITIES:
        packed["detail"] = _jpeg(np.asarray(detail, np.uint8), quality)
        if len(packed["detail"]) <= room:
            break
    return packed


def unpack_compact_frame(state: Mapping[str, Any]) -> NDArray[np.uint8]:
    """The full-size approximation of a :func:`pack_compact_frame` frame.

    Raises ValueError when the state is malformed.
    """
    h, w = (int(v) for v in state["shape"])
    x0, y0, x1, y1 = (int(v) for v in state["box"])
    if not (2 <= h <= MAX_SIDE and 2 <= w <= MAX_SIDE):
        raise ValueError(f"compact frame: bad size {w}x{h}")
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise ValueError("compact frame: the kept region is not inside the frame")
    frame = np.asarray(cv2.resize(unpack_image(state["context"]), (w, h)), np.uint8)
    detail = unpack_image(state["detail"])
    if detail.shape != ((y1 - y0) // 2, (x1 - x0) // 2):
        raise ValueError("compact frame: the kept region has the wrong size")
    frame[y0:y1, x0:x1] = cv2.resize(detail, (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    return frame


def pack_levels(probability: NDArray[np.uint8], low: int, high: int) -> dict[str, Any]:
    """p(object) as 0-255 kept as three levels (below ``low``: 0; above ``high``: 255;
    else 128) at half resolution, PNG: a few kB instead of tens."""
    h, w = probability.shape
    half = cv2.resize(probability, (max(w // 2, 1), max(h // 2, 1)), interpolation=cv2.INTER_AREA)
    levels = np.where(half > high, 255, np.where(half < low, 0, 128)).astype(np.uint8)
    return {"shape": [h, w], "levels": pack_image(levels)}


def unpack_levels(state: Mapping[str, Any]) -> NDArray[np.uint8]:
    """The full-size 0-255 map of :func:`pack_levels`; ValueError if malformed."""
    h, w = (int(v) for v in state["shape"])
    if not (1 <= h <= MAX_SIDE and 1 <= w <= MAX_SIDE):
        raise ValueError(f"p(object) levels: bad size {w}x{h}")
    levels = unpack_image(state["levels"])
    if levels.shape != (max(h // 2, 1), max(w // 2, 1)):
        raise ValueError("p(object) levels have the wrong size")
    return np.asarray(cv2.resize(levels, (w, h), interpolation=cv2.INTER_NEAREST), np.uint8)
