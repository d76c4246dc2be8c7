"""Python client of the efdm-tracker service (REST and WebSocket, sync and asyncio).

Coordinates are ``[x, y]`` pixels everywhere; contours are ``(N, 2)`` float64
arrays.  Frames are encoded images (JPEG, PNG or WebP bytes) or BGR / grey
uint8 arrays, which the client encodes (JPEG quality 90 unless given another
``encoder``).

Examples
--------
>>> from service.client import Client
>>> with Client("http://127.0.0.1:8000") as client:  # doctest: +SKIP
...     for result in client.track(frames, circle=((160, 120), 40)):
...         print(result.frame_index, result.nodes.mean(axis=0))
"""

from service.client._async import AsyncClient
from service.client._common import (
    ApiError,
    CircleSpec,
    Encoder,
    ForcesResult,
    Frame,
    FrameResult,
    ImageEncoder,
    Method,
    Session,
)
from service.client._sync import Client

__all__ = [
    "ApiError",
    "AsyncClient",
    "CircleSpec",
    "Client",
    "Encoder",
    "ForcesResult",
    "Frame",
    "FrameResult",
    "ImageEncoder",
    "Method",
    "Session",
]
