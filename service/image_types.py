"""Image types by their magic bytes: the service and the client both sniff here.

Standard library only, so the client (:mod:`service.client`) imports it
without the web framework.
"""

from __future__ import annotations

__all__ = ["SUPPORTED", "sniff"]

SUPPORTED = frozenset({"image/jpeg", "image/png", "image/webp"})
"""The image types the service decodes."""


def sniff(data: bytes) -> str | None:
    """The image type from its magic bytes.

    Parameters
    ----------
    data : bytes
        An encoded image, or at least its first 12 bytes.

    Returns
    -------
    str or None
        ``"image/png"``, ``"image/jpeg"`` or ``"image/webp"``; None for
        anything else.
    """
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return "image/png"
    if data.startswith(b"\xff\xd8\xff"):
        return "image/jpeg"
    if data[:4] == b"RIFF" and data[8:12] == b"WEBP":
        return "image/webp"
    return None
