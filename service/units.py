"""Sizes as people read them, for the messages of limits (no web code)."""

from __future__ import annotations

TIMES = "\u00d7"
"""The multiplication sign, as people write frame sizes (U+00D7)."""
COMMON_FRAMES = {
    w * h: f"{w}{TIMES}{h}"
    for w, h in ((7680, 4320), (4096, 2160), (3840, 2160), (2560, 1440), (1920, 1080), (1280, 720))
}
"""Frame sizes a pixel limit is likely set to, named in the message when it is one."""


def data_size(count: int) -> str:
    """``count`` bytes as people write them: ``512 bytes``, ``64 KiB``, ``60.0 MiB``."""
    if count < 1024:
        return f"{count} bytes"
    for unit, scale in (("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)):
        if count >= scale:
            value = count / scale
            return f"{value:.0f} {unit}" if value == int(value) else f"{value:.1f} {unit}"
    raise AssertionError("unreachable")  # pragma: no cover


def megapixels(count: int) -> str:
    """``count`` pixels in megapixels, with the frame size it is when it is a common one."""
    name = COMMON_FRAMES.get(count)
    return f"{count / 1e6:.1f} MP" + ("" if name is None else f" ({name})")


def too_many_bytes(what: str, count: int | None, limit: int) -> str:
    """``"body is 60.0 MiB; the limit is 8 MiB"`` (without ``count``: "larger than")."""
    if count is None:
        return f"{what} is larger than the limit of {data_size(limit)}"
    size, most = data_size(count), data_size(limit)
    if size.split()[0].rstrip("0").rstrip(".") == most.split()[0]:  # "64.0 KiB" vs "64 KiB"
        size, most = f"{count:,} bytes", f"{limit:,} bytes"
    return f"{what} is {size}; the limit is {most}"


def too_many_pixels(width: int, height: int, limit: int) -> str:
    """``"frame is 7680x4320 (33.2 MP); the limit is 8.8 MP (4096x2160)"`` (x: :data:`TIMES`)."""
    return (
        f"frame is {width}{TIMES}{height} ({width * height / 1e6:.1f} MP); "
        f"the limit is {megapixels(limit)}"
    )
