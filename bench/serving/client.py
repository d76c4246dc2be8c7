"""The project's Python client (:mod:`service.client`) as the benchmarks use it.

The service and load benchmarks talk to ``efdm serve`` through
:class:`service.client.Client` and :class:`service.client.AsyncClient`: sessions,
REST frames and the closed-loop WebSocket streams (:meth:`AsyncClient.stream`,
one frame in flight) are the client's own code, so the benchmarks measure what
a user of the client gets.  :class:`BenchClient` adds the two things they need
that the client does not offer, and nothing else:

- a compression offer.  The client never offers permessage-deflate; the
  service benchmark measures a stream that offers it (as the ``websockets``
  library does by default, and so most other clients) beside one that does
  not, and notes what the server answered (:attr:`BenchClient.negotiated`);
- the raw connection (:meth:`BenchClient.open_stream`: the client's own
  handshake, URL, headers and size limit) for the open loop, which sends
  frames on a clock while it receives results; ``stream`` alternates the two.

It leans on ``AsyncClient``'s private ``_connect`` (the one method it
overrides; ``@override`` makes mypy fail should it go) and ``_headers``, and on
``service.client._common``.  Should the client grow a compression option and a
public connection, this module shrinks to nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

from typing_extensions import override
from websockets.asyncio.client import ClientConnection, connect

from service.client import AsyncClient, Session
from service.client._common import MAX_MESSAGE, stream_url

Compression = Literal["deflate"] | None
"""What a stream offers: permessage-deflate or nothing."""


def negotiated(ws: ClientConnection, compression: Compression) -> str:
    """What came of the compression offer, for the report's notes."""
    if compression is None:
        return "no compression offered"
    response = ws.response
    accepted = response is not None and "permessage-deflate" in response.headers.get(
        "Sec-WebSocket-Extensions", ""
    )
    if accepted:
        return "permessage-deflate offered and accepted: frames travel compressed"
    return "permessage-deflate offered, the server declined: frames travel uncompressed"


class _Handshake(connect):
    """``websockets``' ``connect``, handing every connection it opens to ``opened``."""

    def __init__(self, uri: str, opened: Callable[[ClientConnection], None], **options: Any):
        super().__init__(uri, **options)
        self._opened = opened

    async def __aenter__(self) -> ClientConnection:
        ws = await super().__aenter__()
        self._opened(ws)
        return ws


class BenchClient(AsyncClient):
    """:class:`service.client.AsyncClient` whose streams make a compression offer.

    Parameters
    ----------
    base_url : str
        The server's root URL.
    compression : {"deflate", None}
        Offer permessage-deflate on every stream, or nothing (the client's way).
    timeout : float
        Seconds for connecting and for each answer.

    Attributes
    ----------
    negotiated : str
        What came of the offer on the last stream opened (for the report's notes).
    """

    def __init__(self, base_url: str, *, compression: Compression, timeout: float) -> None:
        super().__init__(base_url, timeout=timeout)
        self.compression: Compression = compression
        self.negotiated = ""

    def open_stream(self, session: str | Session) -> connect:
        """The session's WebSocket (``async with``): the client's handshake, with the offer."""
        return _Handshake(
            stream_url(self.base_url, session),
            self._opened,
            additional_headers=self._headers,
            user_agent_header=None,
            compression=self.compression,
            open_timeout=self.timeout,
            max_size=MAX_MESSAGE,
        )

    @override
    def _connect(self, session: str | Session) -> connect:
        return self.open_stream(session)  # what AsyncClient.stream connects through

    def _opened(self, ws: ClientConnection) -> None:
        self.negotiated = negotiated(ws, self.compression)
