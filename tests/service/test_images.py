"""Frame decoding: type sniffing, header sizes without decoding, and ``decode_frame``."""

from __future__ import annotations

import struct
import zlib
from typing import Any

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from service.domain_errors import ServiceError
from service.errors import ApiError, as_api_error
from service.image_types import sniff
from service.images import decode_frame, dimensions

LIMITS = {"max_bytes": 8 * 1024 * 1024, "max_pixels": 4096 * 2160}


def picture(h: int = 60, w: int = 80) -> NDArray[np.uint8]:
    """A smooth BGR test picture (compresses well, survives lossy codecs)."""
    rng = np.random.default_rng(7)
    noise = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    return np.asarray(cv2.GaussianBlur(noise, (0, 0), 3), dtype=np.uint8)


def encode(ext: str, img: NDArray[Any], *params: int) -> bytes:
    ok, data = cv2.imencode(ext, img, list(params))
    assert ok
    return data.tobytes()


def png_chunk(kind: bytes, payload: bytes) -> bytes:
    crc = zlib.crc32(kind + payload) & 0xFFFFFFFF
    return struct.pack(">I", len(payload)) + kind + payload + struct.pack(">I", crc)


def png_header_only(w: int, h: int) -> bytes:
    """A PNG signature and an IHDR claiming ``w`` x ``h``, with no pixel data."""
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IEND", b"")


def with_sof_size(jpeg: bytes, w: int, h: int) -> bytes:
    """The JPEG with its frame header (SOF0 or SOF2) claiming ``w`` x ``h``."""
    for marker in (b"\xff\xc0", b"\xff\xc2"):
        i = jpeg.find(marker)
        if i > 0:
            return jpeg[: i + 5] + struct.pack(">HH", h, w) + jpeg[i + 9 :]
    raise AssertionError("no SOF0/SOF2 marker")


def decode(data: bytes, media_type: str | None = None, **limits: int) -> NDArray[np.uint8]:
    return decode_frame(data, media_type, **{**LIMITS, **limits})


def api_error(data: bytes, media_type: str | None = None, **limits: int) -> ApiError:
    with pytest.raises(ServiceError) as info:
        decode(data, media_type, **limits)
    return as_api_error(info.value)


IMG = picture()
BGRA = np.dstack([IMG, np.full(IMG.shape[:2], 128, np.uint8)])
FORMATS = {
    "png": encode(".png", IMG),
    "jpeg": encode(".jpg", IMG, cv2.IMWRITE_JPEG_QUALITY, 95),
    "jpeg-progressive": encode(".jpg", IMG, cv2.IMWRITE_JPEG_PROGRESSIVE, 1),
    "webp-lossy": encode(".webp", IMG, cv2.IMWRITE_WEBP_QUALITY, 90),
    "webp-lossless": encode(".webp", IMG, cv2.IMWRITE_WEBP_QUALITY, 101),
    "webp-extended": encode(".webp", BGRA, cv2.IMWRITE_WEBP_QUALITY, 90),
    "png-16bit": encode(".png", IMG.astype(np.uint16) * 257),
    "png-bgra": encode(".png", BGRA),
    "png-grey": encode(".png", IMG[..., 0]),
}
KINDS = {
    "png": "image/png",
    "jpeg": "image/jpeg",
    "jpeg-progressive": "image/jpeg",
    "webp-lossy": "image/webp",
    "webp-lossless": "image/webp",
    "webp-extended": "image/webp",
    "png-16bit": "image/png",
    "png-bgra": "image/png",
    "png-grey": "image/png",
}


def test_the_webp_fixtures_cover_the_three_container_layouts() -> None:
    assert FORMATS["webp-lossy"][12:16] == b"VP8 "
    assert FORMATS["webp-lossless"][12:16] == b"VP8L"
    assert FORMATS["webp-extended"][12:16] == b"VP8X"
    assert b"\xff\xc2" in FORMATS["jpeg-progressive"]
    assert b"\xff\xc2" not in FORMATS["jpeg"]


@pytest.mark.parametrize("name", list(FORMATS))
def test_sniff_and_dimensions(name: str) -> None:
    data = FORMATS[name]
    assert sniff(data) == KINDS[name]
    assert dimensions(data, KINDS[name]) == (80, 60)


@pytest.mark.parametrize("name", list(FORMATS))
def test_decode_gives_uint8_bgr_or_grey_of_the_right_size(name: str) -> None:
    frame = decode(FORMATS[name])
    assert frame.dtype == np.uint8
    expected = (60, 80) if name == "png-grey" else (60, 80, 3)
    assert frame.shape == expected
    reference = IMG[..., 0] if name == "png-grey" else IMG
    error = np.abs(frame.astype(np.int16) - reference.astype(np.int16))
    if name in ("png", "png-16bit", "png-bgra", "png-grey", "webp-lossless"):
        assert error.max() == 0  # lossless: exactly the picture (16 bit: its high byte)
    else:
        assert error.mean() < 4


@pytest.mark.parametrize(
    "data",
    [
        b"",
        b"GIF89a" + b"\0" * 40,
        b"BM" + b"\0" * 60,
        b"II*\0" + b"\0" * 40,
        b"RIFF\0\0\0\0WAVEfmt ",
        b"\x89PNG\r\n",
        b"\xff\xd8",
        b"<html></html>",
    ],
)
def test_sniff_rejects_other_formats(data: bytes) -> None:
    assert sniff(data) is None


@pytest.mark.parametrize(
    ("data", "kind"),
    [
        (b"\x89PNG\r\n\x1a\n", "image/png"),
        (b"\x89PNG\r\n\x1a\n" + png_chunk(b"tEXt", b"a\0b"), "image/png"),
        (b"\xff\xd8\xff", "image/jpeg"),
        (b"\xff\xd8\xff\xe0\x00\x10JFIF\x00", "image/jpeg"),
        (b"RIFF\0\0\0\0WEBPVP8Z\0\0\0\0" + b"\0" * 20, "image/webp"),
        (b"RIFF\0\0\0\0WEBPVP8 ", "image/webp"),
    ],
)
def test_dimensions_of_unreadable_headers_is_none(data: bytes, kind: str) -> None:
    assert dimensions(data, kind) is None


def test_dimensions_skip_large_segments_before_the_frame_header() -> None:
    jpeg = FORMATS["jpeg"]
    app1 = b"\xff\xe1" + struct.pack(">H", 60002) + b"Exif\0\0" + b"x" * 59994
    data = jpeg[:2] + app1 + jpeg[2:]
    assert dimensions(data, "image/jpeg") == (80, 60)
    assert decode(data).shape == (60, 80, 3)


def test_jpeg_fill_bytes_before_a_marker_are_allowed() -> None:
    """ITU T.81 B.1.1.2: any marker may be preceded by 0xFF fill bytes; decoders accept them."""
    jpeg = FORMATS["jpeg"]
    i = jpeg.index(b"\xff\xc0")
    padded = jpeg[:i] + b"\xff\xff\xff" + jpeg[i:]
    assert cv2.imdecode(np.frombuffer(padded, np.uint8), cv2.IMREAD_UNCHANGED) is not None
    assert dimensions(padded, "image/jpeg") == (80, 60)
    assert decode(padded).shape == (60, 80, 3)


@pytest.mark.parametrize("name", ["png", "jpeg", "jpeg-progressive", "webp-lossy", "png-16bit"])
@pytest.mark.parametrize("keep", [0.5, 0.1])
def test_truncated_files_are_bad_images(name: str, keep: float) -> None:
    data = FORMATS[name]
    error = api_error(data[: int(len(data) * keep)])
    assert (error.status, error.code) == (400, "bad_image")


@pytest.mark.parametrize("name", list(FORMATS))
def test_headers_only_are_bad_images(name: str) -> None:
    error = api_error(FORMATS[name][:40])
    assert (error.status, error.code) == (400, "bad_image")


def test_random_bytes_and_empty_bodies_are_bad_images() -> None:
    rng = np.random.default_rng(3)
    assert api_error(rng.integers(0, 256, 5000, dtype=np.uint8).tobytes()).status == 400
    assert api_error(b"").status == 400
    # the right magic, garbage after it
    assert api_error(b"\xff\xd8\xff" + b"\x00" * 100).status == 400
    assert api_error(b"\x89PNG\r\n\x1a\n" + b"\x00" * 100).status == 400


def never_decode(*_: object) -> None:
    raise AssertionError("cv2.imdecode must not be called")


def test_a_png_header_claiming_20000_squared_is_refused_without_decoding(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    data = png_header_only(20000, 20000)
    assert dimensions(data, "image/png") == (20000, 20000)
    monkeypatch.setattr(cv2, "imdecode", never_decode)
    error = api_error(data, "image/png")
    assert (error.status, error.code) == (413, "too_large")
    assert "20000\u00d720000 (400.0 MP)" in error.message


@pytest.mark.parametrize("name", ["jpeg", "jpeg-progressive"])
def test_a_jpeg_frame_header_claiming_a_huge_size_is_refused_without_decoding(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = with_sof_size(FORMATS[name], 30000, 30000)
    assert dimensions(data, "image/jpeg") == (30000, 30000)
    monkeypatch.setattr(cv2, "imdecode", never_decode)
    assert api_error(data).status == 413


@pytest.mark.parametrize(
    ("name", "patch"),
    [
        ("webp-extended", lambda d: d[:24] + (16383).to_bytes(3, "little") * 2 + d[30:]),
        ("webp-lossy", lambda d: d[:26] + struct.pack("<HH", 16383, 16383) + d[30:]),
        ("webp-lossless", lambda d: d[:21] + (0x0FFFFFFF).to_bytes(4, "little") + d[25:]),
    ],
)
def test_a_webp_header_claiming_a_huge_size_is_refused_without_decoding(
    name: str, patch: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    data: bytes = patch(FORMATS[name])
    w, h = dimensions(data, "image/webp") or (0, 0)
    assert w * h > LIMITS["max_pixels"]
    monkeypatch.setattr(cv2, "imdecode", never_decode)
    assert api_error(data).status == 413


def png_with_size(png: bytes, w: int, h: int) -> bytes:
    """The PNG with its IHDR (and its CRC) rewritten to claim ``w`` x ``h``."""
    ihdr = struct.pack(">II", w, h) + png[24:29]
    return png[:8] + png_chunk(b"IHDR", ihdr) + png[33:]


@pytest.mark.parametrize(
    "data",
    [with_sof_size(FORMATS["jpeg"], 8, 8), png_with_size(FORMATS["png"], 8, 8)],
    ids=["jpeg", "png"],
)
def test_a_header_claiming_less_than_the_data_never_decodes_larger(data: bytes) -> None:
    """A lying small header: unreadable (400) or decoded at the declared size, never more."""
    assert dimensions(data, sniff(data) or "") == (8, 8)
    outcome: NDArray[np.uint8] | ApiError
    try:
        outcome = decode(data, max_pixels=64)
    except ServiceError as exc:
        outcome = as_api_error(exc)
    if isinstance(outcome, ApiError):
        assert (outcome.status, outcome.code) == (400, "bad_image")
    else:
        assert outcome.shape[:2] == (8, 8)


def test_pixel_limit_counts_width_times_height() -> None:
    data = FORMATS["png"]
    assert decode(data, max_pixels=80 * 60).shape == (60, 80, 3)
    error = api_error(data, max_pixels=80 * 60 - 1)
    assert (error.status, error.code) == (413, "too_large")


def test_byte_limit_is_checked_first() -> None:
    data = FORMATS["png"]
    assert decode(data, max_bytes=len(data)).shape == (60, 80, 3)
    error = api_error(data, "text/plain", max_bytes=len(data) - 1)
    assert (error.status, error.code) == (413, "too_large")


@pytest.mark.parametrize(
    "media_type",
    [None, "", "image/png", "IMAGE/PNG", "image/png; charset=binary", "application/octet-stream"],
)
def test_accepted_declared_types(media_type: str | None) -> None:
    assert decode(FORMATS["png"], media_type).shape == (60, 80, 3)


def test_the_declared_image_type_need_not_match_the_content() -> None:
    """The content is sniffed; the declared type only has to be an image type we take."""
    assert decode(FORMATS["jpeg"], "image/png").shape == (60, 80, 3)


@pytest.mark.parametrize(
    "media_type", ["text/plain", "image/gif", "application/json", "multipart/mixed"]
)
def test_other_declared_types_are_unsupported(media_type: str) -> None:
    error = api_error(FORMATS["png"], media_type)
    assert (error.status, error.code) == (415, "unsupported_media_type")
