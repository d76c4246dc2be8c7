"""WebSocket clients of ``WS /v1/sessions/{id}/stream`` for the service benchmark.

Closed loop: the next frame is sent when the previous result arrived, so the
server drops nothing.  Open loop: frames are sent on a fixed clock, faster
than they are tracked; the server keeps only the newest waiting frame and
reports the skipped ones in ``dropped``.  Every wait has a timeout and every
loop a frame count and a deadline.
"""

from __future__ import annotations

import asyncio
import json
import time
from dataclasses import dataclass
from typing import Any, Literal

import httpx
from websockets.asyncio.client import ClientConnection, connect

from _service_data import JpegClip
from _service_server import Server, create_session
from _service_stats import FrameRun, Measurement, handler_timed, metered

RECV_TIMEOUT = 20.0
Compression = Literal["deflate"] | None


@dataclass(frozen=True, slots=True)
class StreamSpec:
    """How to stream: row name, compression offer and the time limit."""

    name: str
    compression: Compression
    deadline: float


def _frame_message(raw: str | bytes, row: Measurement) -> dict[str, Any] | None:
    message: dict[str, Any] = json.loads(raw)
    if message.get("type") != "frame":
        row.errors += 1
        return None
    return message


async def _open(server: Server, session_id: str, compression: Compression) -> ClientConnection:
    url = f"{server.ws_url}/v1/sessions/{session_id}/stream"
    return await connect(url, compression=compression, max_size=2**22, open_timeout=10)


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


def _new_session(server: Server, clip: JpegClip) -> str:
    with httpx.Client(base_url=server.url, timeout=10.0) as client:
        return create_session(client, clip.nodes)


async def _closed_loop(
    ws: ClientConnection, clip: JpegClip, spec: StreamSpec, row: Measurement
) -> FrameRun:
    run = FrameRun(row)
    start = time.perf_counter()
    for data in clip.frames:
        if time.monotonic() > spec.deadline:
            break
        t0 = time.perf_counter()
        await ws.send(data)
        row.sent += 1
        raw = await asyncio.wait_for(ws.recv(), RECV_TIMEOUT)
        row.latencies_ms.append((time.perf_counter() - t0) * 1e3)
        message = _frame_message(raw, row)
        if message is not None:
            row.items += 1
            row.dropped += int(message["dropped"])
            row.server_ms.append(float(message["elapsed_ms"]))
            run.nodes.append(message["nodes"])
    row.seconds = time.perf_counter() - start
    return run


async def _stream_closed(server: Server, clip: JpegClip, spec: StreamSpec) -> FrameRun:
    session_id = await asyncio.to_thread(_new_session, server, clip)
    row = Measurement(spec.name, "frames")
    async with await _open(server, session_id, spec.compression) as ws:
        row.note = negotiated(ws, spec.compression)
        with handler_timed(row, server.url, "websocket"), metered(row, server.pid):
            return await _closed_loop(ws, clip, spec, row)


def ws_closed_loop(server: Server, clip: JpegClip, spec: StreamSpec) -> FrameRun:
    """One session streaming ``clip`` closed-loop (connection set-up not timed)."""
    return asyncio.run(_stream_closed(server, clip, spec))


async def _concurrent(
    server: Server, clips: list[JpegClip], sessions: int, spec: StreamSpec
) -> Measurement:
    chosen = [clips[i % len(clips)] for i in range(sessions)]
    ids = [await asyncio.to_thread(_new_session, server, clip) for clip in chosen]
    sockets = [await _open(server, sid, spec.compression) for sid in ids]
    row = Measurement(spec.name, "frames", clients=sessions)
    row.note = negotiated(sockets[0], spec.compression)
    parts = [Measurement(spec.name, "frames") for _ in sockets]
    try:
        with metered(row, server.pid):
            start = time.perf_counter()
            await asyncio.gather(
                *(
                    _closed_loop(ws, clip, spec, part)
                    for ws, clip, part in zip(sockets, chosen, parts, strict=True)
                )
            )
            wall = time.perf_counter() - start
    finally:
        await asyncio.gather(*(ws.close() for ws in sockets), return_exceptions=True)
    for part in parts:
        row.add(part)
    row.seconds = wall
    return row


def ws_concurrent(
    server: Server, clips: list[JpegClip], sessions: int, spec: StreamSpec
) -> Measurement:
    """``sessions`` closed-loop streams at once (clips assigned in turn); wall-clock rate."""
    return asyncio.run(_concurrent(server, clips, sessions, spec))


async def _send_on_clock(
    ws: ClientConnection, clip: JpegClip, rate: float, sent_at: list[float], deadline: float
) -> None:
    start = time.perf_counter()
    for i, data in enumerate(clip.frames):
        if time.monotonic() > deadline:
            return
        delay = start + i / rate - time.perf_counter()
        if delay > 0:
            await asyncio.sleep(delay)
        sent_at.append(time.perf_counter())
        await ws.send(data)


async def _receive_open(
    ws: ClientConnection, row: Measurement, sent_at: list[float], sender: asyncio.Task[None]
) -> float:
    """Receive results until every sent frame is tracked or skipped; returns the last time."""
    accounted = 0  # frames tracked or dropped so far, in sending order
    last = time.perf_counter()
    while not (sender.done() and accounted >= len(sent_at)):
        raw = await asyncio.wait_for(ws.recv(), RECV_TIMEOUT)
        last = time.perf_counter()
        message = _frame_message(raw, row)
        if message is None:
            accounted += 1
            continue
        dropped = int(message["dropped"])
        accounted += dropped + 1
        row.items += 1
        row.dropped += dropped
        row.server_ms.append(float(message["elapsed_ms"]))
        if 0 < accounted <= len(sent_at):
            row.latencies_ms.append((last - sent_at[accounted - 1]) * 1e3)
    return last


async def _stream_open(
    server: Server, clip: JpegClip, rate: float, spec: StreamSpec
) -> Measurement:
    session_id = await asyncio.to_thread(_new_session, server, clip)
    row = Measurement(spec.name, "frames")
    sent_at: list[float] = []
    async with await _open(server, session_id, spec.compression) as ws:
        row.note = negotiated(ws, spec.compression)
        with metered(row, server.pid):
            start = time.perf_counter()
            sender = asyncio.create_task(_send_on_clock(ws, clip, rate, sent_at, spec.deadline))
            try:
                last = await _receive_open(ws, row, sent_at, sender)
            finally:
                sender.cancel()
    row.sent = len(sent_at)
    row.seconds = last - start
    return row


def ws_open_loop(server: Server, clip: JpegClip, rate: float, spec: StreamSpec) -> Measurement:
    """Stream ``clip`` at ``rate`` frames/s regardless of results; count the skipped frames.

    Latency is from sending a frame to receiving its result (for frames that
    were tracked, not skipped).
    """
    return asyncio.run(_stream_open(server, clip, rate, spec))
