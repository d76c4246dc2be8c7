"""service.units: the sizes of limit messages, as people read them."""

from __future__ import annotations

import pytest

from service.units import TIMES, data_size, megapixels, too_many_bytes, too_many_pixels


@pytest.mark.parametrize(
    ("count", "text"),
    [
        (0, "0 bytes"),
        (1023, "1023 bytes"),
        (1024, "1 KiB"),
        (1536, "1.5 KiB"),
        (8 << 20, "8 MiB"),
        (60 << 20, "60 MiB"),
        (int(60.04 * (1 << 20)), "60.0 MiB"),
        (3 << 30, "3 GiB"),
    ],
)
def test_data_size(count: int, text: str) -> None:
    assert data_size(count) == text


def test_too_many_bytes_reads_as_people_think() -> None:
    assert too_many_bytes("body", 60 << 20, 8 << 20) == "body is 60 MiB; the limit is 8 MiB"
    assert too_many_bytes("body", None, 2 << 20) == "body is larger than the limit of 2 MiB"
    # sizes that would round alike are given exactly
    assert too_many_bytes("frame", 65539, 65536) == (
        "frame is 65,539 bytes; the limit is 65,536 bytes"
    )


def test_too_many_pixels_names_a_common_limit() -> None:
    assert too_many_pixels(7680, 4320, 4096 * 2160) == (
        f"frame is 7680{TIMES}4320 (33.2 MP); the limit is 8.8 MP (4096{TIMES}2160)"
    )
    assert megapixels(5_000_000) == "5.0 MP"  # not a frame size anyone names
