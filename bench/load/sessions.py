"""Concurrent WebSocket sessions for the load benchmark, closed loop, one asyncio process.

Session ``i`` streams from replica ``i mod R`` (round robin) and is created
through replica ``i + 1 mod R``: with two replicas every session is made on
one and tracked on the other, through the shared store.  Each session sends
one untimed frame first; then all start together, each sending its next frame
when the previous result arrived, until its frame budget or the row's
deadline.  Every wait has a timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import httpx
import numpy as np
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import WebSocketException

from _service_data import JpegClip, encode
from _service_server import Server
from _service_stats import Measurement
from engine.geometry import mask_to_contour
from engine.synthetic import make_sequence

RECV_TIMEOUT = 30.0
OPEN_TIMEOUT = 20.0


Clip = JpegClip
"""The frames every session streams (the service benchmark's clip type)."""


def synthetic_clip(length: int, nodes: int, size: tuple[int, int] = (240, 320)) -> Clip:
    """An ``engine.synthetic`` "plain" sequence as JPEG, played forward then back.

    Forward-and-back keeps the motion continuous when a session loops over it.
    """
    sequence = make_sequence("plain", seed=0, length=length, size=size)
    jpeg = [encode(np.asarray(f, dtype=np.uint8)) for f in sequence.frames]
    order = [*jpeg, *jpeg[-2:0:-1]]
    contour = mask_to_contour(np.asarray(sequence.masks[0], dtype=np.uint8), nodes).tolist()
    return Clip(
        f"synthetic plain {size[1]}x{size[0]}", "engine.synthetic", tuple(order), contour, size
    )


def cycle(clip: Clip, start: int) -> Iterator[bytes]:
    """The clip's frames from ``start`` on, looping forever."""
    i = start
    while True:
        yield clip.frames[i % len(clip.frames)]
        i += 1


async def _create(servers: Sequence[Server], clip: Clip, sessions: int) -> list[str]:
    clients = [httpx.AsyncClient(base_url=s.url, timeout=OPEN_TIMEOUT) for s in servers]
    try:
        ids = []
        for i in range(sessions):
            client = clients[(i + 1) % len(clients)]
            response = await client.post("/v1/sessions", json={"nodes": clip.nodes})
            response.raise_for_status()
            ids.append(str(response.json()["id"]))
        return ids
    finally:
        await asyncio.gather(*(c.aclose() for c in clients))


async def _open(server: Server, session_id: str) -> ClientConnection:
    url = f"{server.ws_url}/v1/sessions/{session_id}/stream"
    return await connect(url, compression=None, max_size=2**22, open_timeout=OPEN_TIMEOUT)


async def _exchange(ws: ClientConnection, data: bytes, row: Measurement) -> bool:
    """Send a frame and count its answer; False when the session cannot go on."""
    t0 = time.perf_counter()
    row.sent += 1
    try:
        await ws.send(data)
        raw = await asyncio.wait_for(ws.recv(), RECV_TIMEOUT)
    except (TimeoutError, WebSocketException, OSError):
        row.errors += 1
        return False
    row.latencies_ms.append((time.perf_counter() - t0) * 1e3)
    message = json.loads(raw)
    if message.get("type") != "frame":
        row.errors += 1
        return True
    row.items += 1
    row.dropped += int(message.get("dropped", 0))
    row.server_ms.append(float(message.get("elapsed_ms", float("nan"))))
    return True


async def _stream(
    ws: ClientConnection, frames: Iterator[bytes], budget: int, deadline: float, row: Measurement
) -> None:
    for _ in range(budget):
        if time.monotonic() > deadline or not await _exchange(ws, next(frames), row):
            return


@dataclass(frozen=True, slots=True)
class Load:
    """One row's load: sessions, frames per session and the time limit."""

    sessions: int
    frames_per_session: int
    seconds: float


Hook = Callable[[], None]


async def _run(
    servers: Sequence[Server], clip: Clip, load: Load, before: Hook, after: Hook
) -> Measurement:
    ids = await _create(servers, clip, load.sessions)
    opened = await asyncio.gather(
        *(_open(servers[i % len(servers)], sid) for i, sid in enumerate(ids)),
        return_exceptions=True,
    )
    sockets = [ws for ws in opened if isinstance(ws, ClientConnection)]
    row = Measurement("", "frames", clients=load.sessions)
    row.errors += len(opened) - len(sockets)
    parts = [Measurement("", "frames") for _ in sockets]
    try:
        warm = [Measurement("", "frames") for _ in sockets]
        await asyncio.gather(
            *(_exchange(ws, clip.frames[0], w) for ws, w in zip(sockets, warm, strict=True))
        )
        row.errors += sum(w.errors for w in warm)
        before()
        start = time.perf_counter()
        deadline = time.monotonic() + load.seconds
        await asyncio.gather(
            *(
                _stream(ws, cycle(clip, 1), load.frames_per_session, deadline, part)
                for ws, part in zip(sockets, parts, strict=True)
            )
        )
        wall = time.perf_counter() - start
        after()
    finally:
        with contextlib.suppress(Exception):
            await asyncio.wait_for(
                asyncio.gather(*(ws.close() for ws in sockets), return_exceptions=True),
                OPEN_TIMEOUT,
            )
    for part in parts:
        row.add(part)
    row.seconds = wall
    return row


def run_sessions(
    servers: Sequence[Server], clip: Clip, load: Load, before: Hook, after: Hook
) -> Measurement:
    """Stream ``load.sessions`` closed-loop sessions round-robin over ``servers``.

    Parameters
    ----------
    servers : sequence of Server
        The replicas (sharing one store when more than one).
    clip : Clip
        Frames to stream; every session starts from the clip's first contour.
    load : Load
        Sessions, frame budget per session and time limit of the timed part.
    before, after : callable
        Called right before and after the timed part (counter snapshots).

    Returns
    -------
    Measurement
        Frames tracked, latencies, dropped frames and errors of the timed
        part; ``seconds`` is its wall time.  Sessions that failed to open or
        to warm up count as errors.
    """
    return asyncio.run(_run(servers, clip, load, before, after))
