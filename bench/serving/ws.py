"""WebSocket streams (``WS /v1/sessions/{id}/stream``) for the service and load benchmarks.

Closed loop (:func:`closed_loops`): :meth:`service.client.AsyncClient.stream`
with one frame in flight, so the next frame goes when the previous result
arrived and the server drops nothing.  Sessions are connected (and, if asked,
warmed up with one untimed frame) first; then they are timed together.  Open
loop (:func:`ws_open_loop`): frames are sent on a fixed clock, faster than
they are tracked, while results are received; the server keeps only the
newest waiting frame and reports the skipped ones in ``dropped``.  Every wait
has a timeout and every loop a frame count and a deadline.
"""

from __future__ import annotations

import asyncio
import math
import time
from collections.abc import AsyncIterator, Callable, Iterable, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass

from websockets.asyncio.client import ClientConnection
from websockets.exceptions import WebSocketException

from bench.serving.client import BenchClient, Compression
from bench.serving.data import JpegClip
from bench.serving.server import TIMEOUT, Server
from bench.serving.stats import FrameRun, Measurement, Nodes, handler_timed, metered, together
from service.client import ApiError
from service.client._common import parse_message

STREAM_ERRORS = (ApiError, TimeoutError, WebSocketException, OSError)
"""What ends a session's stream early: it counts as one error."""
Timed = Callable[[], AbstractContextManager[object]]
"""What to read around the timed part (CPU time, server metrics, Redis counters)."""


@dataclass(frozen=True, slots=True)
class Plan:
    """One session of :func:`closed_loops`.

    Attributes
    ----------
    client : BenchClient
        The client of the server that streams the session.
    session : str
        Session id.
    frames : iterable of bytes
        The timed frames, in order (the session stops at their end or the deadline).
    warm : bytes or None
        One untimed frame sent before the timed part.
    """

    client: BenchClient
    session: str
    frames: Iterable[bytes]
    warm: bytes | None = None


class _Countdown:
    """An event set once ``count`` sessions have called :meth:`down`."""

    def __init__(self, count: int) -> None:
        self.count = count
        self.zero = asyncio.Event()
        if count <= 0:
            self.zero.set()

    def down(self) -> None:
        self.count -= 1
        if self.count <= 0:
            self.zero.set()


class _Gate:
    """Holds every session's frames until all are ready, then times them together."""

    def __init__(self, sessions: int) -> None:
        self.ready = _Countdown(sessions)  # connected (and warm), or failed
        self.done = _Countdown(sessions)  # through their frames, or failed
        self.go = asyncio.Event()
        self.released = asyncio.Event()  # the timed part is over: sockets may close
        self.deadline = math.inf

    def open(self, seconds: float) -> None:
        self.deadline = time.monotonic() + seconds
        self.go.set()

    def release(self) -> None:
        self.go.set()
        self.released.set()


async def _session(plan: Plan, gate: _Gate, row: Measurement) -> list[Nodes]:
    """Stream one plan through the client, counting into ``row``; the tracked contours."""
    nodes: list[Nodes] = []
    sent_at: list[float] = []
    marked: set[str] = set()

    def mark(countdown: _Countdown, name: str) -> None:
        if name not in marked:
            marked.add(name)
            countdown.down()

    async def frames() -> AsyncIterator[bytes]:
        # The client asks for a frame when the previous result has arrived.
        if plan.warm is not None:
            yield plan.warm
        mark(gate.ready, "ready")
        await gate.go.wait()
        for data in plan.frames:
            if time.monotonic() > gate.deadline:
                break
            sent_at.append(time.perf_counter())
            yield data
        mark(gate.done, "done")
        await gate.released.wait()  # keep the socket open until the timed part is over

    try:
        async for result in plan.client.stream(plan.session, frames()):
            if not sent_at:
                continue  # the warm-up frame's result
            row.latencies_ms.append((time.perf_counter() - sent_at[-1]) * 1e3)
            row.items += 1
            row.dropped += result.dropped
            row.server_ms.append(result.elapsed_ms)
            nodes.append(result.nodes)
    except STREAM_ERRORS:
        row.errors += 1
    finally:
        mark(gate.ready, "ready")
        mark(gate.done, "done")
        row.sent = len(sent_at)
    return nodes


async def closed_loops(
    plans: Sequence[Plan], seconds: float, row: Measurement, timed: Timed
) -> list[list[Nodes]]:
    """Stream every plan closed loop, all at once, pooled into ``row``.

    The timed part starts when every session is connected and has its warm-up
    result, runs inside ``timed()``, stops sending after ``seconds`` and ends
    when the last session has its last result; ``row.seconds`` is its wall
    time.  Sockets close after it.  A session that fails counts one error.

    Returns
    -------
    list of list of Nodes
        Per session, the contour of every tracked frame.
    """
    gate = _Gate(len(plans))
    parts = [Measurement(row.name, row.kind) for _ in plans]
    tasks = [
        asyncio.create_task(_session(plan, gate, part))
        for plan, part in zip(plans, parts, strict=True)
    ]
    try:
        await gate.ready.zero.wait()
        with timed():
            start = time.perf_counter()
            gate.open(seconds)
            await gate.done.zero.wait()
            wall = time.perf_counter() - start
    finally:
        gate.release()
        nodes = await asyncio.gather(*tasks)
    for part in parts:
        row.add(part)
    row.seconds = wall
    return nodes


@dataclass(frozen=True, slots=True)
class StreamSpec:
    """How to stream: row name, compression offer and the time limit (seconds)."""

    name: str
    compression: Compression
    seconds: float


def _client(server: Server, spec: StreamSpec) -> BenchClient:
    return BenchClient(server.url, compression=spec.compression, timeout=TIMEOUT)


async def _stream_closed(server: Server, clip: JpegClip, spec: StreamSpec) -> FrameRun:
    client = _client(server, spec)  # bound first: AsyncClient.__aenter__ returns AsyncClient
    async with client:
        session = await client.create_session(clip.nodes)
        row = Measurement(spec.name, "frames")

        def timed() -> AbstractContextManager[object]:
            return together(handler_timed(row, server.url, "websocket"), metered(row, [server.pid]))

        [nodes] = await closed_loops(
            [Plan(client, session.id, clip.frames)], spec.seconds, row, timed
        )
        row.note = client.negotiated
    return FrameRun(row, nodes)


def ws_closed_loop(server: Server, clip: JpegClip, spec: StreamSpec) -> FrameRun:
    """One session streaming ``clip`` closed loop (connection set-up not timed)."""
    return asyncio.run(_stream_closed(server, clip, spec))


async def _concurrent(
    server: Server, clips: list[JpegClip], sessions: int, spec: StreamSpec
) -> Measurement:
    chosen = [clips[i % len(clips)] for i in range(sessions)]
    row = Measurement(spec.name, "frames", clients=sessions)
    client = _client(server, spec)
    async with client:
        ids = [(await client.create_session(clip.nodes)).id for clip in chosen]
        plans = [Plan(client, sid, clip.frames) for sid, clip in zip(ids, chosen, strict=True)]
        await closed_loops(plans, spec.seconds, row, lambda: metered(row, [server.pid]))
        row.note = client.negotiated
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
        raw = await asyncio.wait_for(ws.recv(), TIMEOUT)
        last = time.perf_counter()
        try:
            result = parse_message(raw)
        except ApiError:
            result = None
        if result is None:
            row.errors += 1
            accounted += 1
            continue
        accounted += result.dropped + 1
        row.items += 1
        row.dropped += result.dropped
        row.server_ms.append(result.elapsed_ms)
        if 0 < accounted <= len(sent_at):
            row.latencies_ms.append((last - sent_at[accounted - 1]) * 1e3)
    return last


async def _stream_open(
    server: Server, clip: JpegClip, rate: float, spec: StreamSpec
) -> Measurement:
    row = Measurement(spec.name, "frames")
    sent_at: list[float] = []
    client = _client(server, spec)
    async with client:
        session = await client.create_session(clip.nodes)
        deadline = time.monotonic() + spec.seconds
        async with client.open_stream(session) as ws:
            row.note = client.negotiated
            with metered(row, [server.pid]):
                start = time.perf_counter()
                sender = asyncio.create_task(_send_on_clock(ws, clip, rate, sent_at, deadline))
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
