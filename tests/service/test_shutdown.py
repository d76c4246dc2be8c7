"""Graceful shutdown: the stream registry, and SIGTERM on a busy real ``efdm serve``.

The registry (:mod:`service.shutdown`) is tested in-process with a stand-in
socket.  Then a real server stops accepting connections, answers the REST frame and the
WebSocket frame it is tracking, closes the stream with ``1001 going away``
(after committing its session) and exits with code 0.  The frames are as
large as the default limits allow (4096 x 2160: a few hundred ms to track)
so that both are still being tracked when uvicorn notices the signal (it
looks every 0.1 s); the assertions hold either way, and every wait is bounded.
"""

from __future__ import annotations

import asyncio
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import httpx
import pytest
from starlette.websockets import WebSocket
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from service.shutdown import StreamRegistry
from tests.service.conftest import RedisServer, disc_frame, free_port

SHAPE = (2160, 4096)  # EFDM_MAX_FRAME_PIXELS by default: 4096 x 2160
CX, CY, RADIUS = 2048.0, 1080.0, 900
CIRCLE: dict[str, Any] = {"circle": {"center": [CX, CY], "radius": RADIUS, "count": 256}}
MAX_RECEIVES = 5  # results before the close frame: at most the one in flight
WAIT = 60.0  # bound of any single wait (start-up included)


@pytest.fixture
def anyio_backend() -> str:
    return "asyncio"


class FakeSocket:
    """Records close calls; closing ends the stream's handler, as a client's answer would."""

    def __init__(self, registry: StreamRegistry) -> None:
        self.registry = registry
        self.events: list[str] = []
        self.stream = registry.register(cast(WebSocket, self))

    async def close(self, code: int = 1000, reason: str | None = None) -> None:
        self.events.append(f"close {code} {reason}")
        self.registry.unregister(self.stream)


async def settle() -> None:
    """Let every ready task run until it waits on something."""
    for _ in range(20):
        await asyncio.sleep(0)


@pytest.mark.anyio
async def test_close_all_waits_for_the_frame_in_flight_then_closes_with_1001() -> None:
    registry = StreamRegistry()
    socket = FakeSocket(registry)
    release = asyncio.Event()

    async def track_one_frame() -> None:
        async with socket.stream.in_flight():
            await release.wait()
            socket.events.append("result sent")

    worker = asyncio.create_task(track_one_frame())
    await settle()
    closing = asyncio.create_task(registry.close_all())
    await settle()
    assert socket.events == []  # still tracking: not closed
    release.set()
    assert await closing == 1
    assert socket.events == ["result sent", "close 1001 server shutting down"]
    assert len(registry) == 0
    await worker

    later = asyncio.create_task(track_one_frame())  # nothing new starts once closing
    await settle()
    assert not later.done()
    later.cancel()


@pytest.mark.anyio
async def test_a_stream_still_busy_at_the_deadline_is_closed_anyway() -> None:
    registry = StreamRegistry()
    socket = FakeSocket(registry)
    stuck = asyncio.Event()

    async def never_done() -> None:
        async with socket.stream.in_flight():
            await stuck.wait()

    worker = asyncio.create_task(never_done())
    await settle()
    assert await registry.close_all(code=1001, timeout=0.01) == 1
    assert socket.events == ["close 1001 server shutting down"]
    worker.cancel()


@pytest.mark.anyio
async def test_streams_registered_during_shutdown_are_closed_at_once() -> None:
    registry = StreamRegistry()
    assert await registry.close_all() == 0
    socket = FakeSocket(registry)
    await settle()
    assert socket.events == ["close 1001 server shutting down"]
    assert len(registry) == 0


@dataclass
class Served:
    """A running ``efdm serve`` subprocess and where its output goes."""

    process: subprocess.Popen[bytes]
    url: str
    ws_url: str
    log: Path


@dataclass
class RestCall:
    """A REST /frames request on its own thread; ``sent`` once the body is out."""

    sent: threading.Event = field(default_factory=threading.Event)
    status: int = 0
    body: dict[str, Any] = field(default_factory=dict)
    error: BaseException | None = None


def start(tmp_path: Path, env: dict[str, str]) -> Served:
    """``python -m efdm_cli serve`` on a free port; returns once /healthz answers."""
    port = free_port()
    log = tmp_path / "server.log"
    with log.open("wb") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "efdm_cli", "serve", "--port", str(port)],
            env={**os.environ, "EFDM_LOG_LEVEL": "warning", **env},
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
    url = f"http://127.0.0.1:{port}"
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline and process.poll() is None:
        try:
            if httpx.get(f"{url}/healthz", timeout=1).status_code == 200:
                return Served(process, url, f"ws://127.0.0.1:{port}", log)
        except httpx.TransportError:
            time.sleep(0.05)
    process.kill()
    process.wait()
    raise AssertionError(f"efdm serve did not start: {log.read_text(errors='replace')}")


@pytest.fixture(scope="module")
def frames() -> list[bytes]:
    return [disc_frame(CX + 3 * i, CY, r=RADIUS, shape=SHAPE) for i in range(3)]


@pytest.fixture(params=["memory", "redis"])
def served(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[Served, str]]:
    """The server with the in-memory store, or with Redis writing streams through rarely."""
    env: dict[str, str] = {}
    redis_url = ""
    if request.param == "redis":
        redis: RedisServer = request.getfixturevalue("redis_server")
        redis_url = redis.url
        env = {"EFDM_REDIS_URL": redis_url, "EFDM_STREAM_COMMIT_EVERY": "1000"}
    server = start(tmp_path, env)
    try:
        yield server, redis_url
    finally:
        if server.process.poll() is None:
            server.process.kill()
        server.process.wait()


def post_frame(url: str, session_id: str, data: bytes, call: RestCall) -> None:
    """POST one frame; record the answer (or the error) in ``call``."""

    def trace(event: str, info: dict[str, Any]) -> None:
        if event == "http11.send_request_body.complete":
            call.sent.set()

    try:
        with httpx.Client(base_url=url, timeout=WAIT) as client:
            response = client.post(
                f"/v1/sessions/{session_id}/frames",
                content=data,
                headers={"content-type": "image/jpeg"},
                extensions={"trace": trace},
            )
        call.status = response.status_code
        call.body = response.json()
    except BaseException as exc:  # reported by the test, not lost in the thread
        call.error = exc
    finally:
        call.sent.set()


def stored_version(redis_url: str, session_id: str) -> int:
    """The version of a session as Redis holds it."""
    import redis

    with redis.Redis.from_url(redis_url) as client:
        value = client.hget(f"efdm:session:{session_id}", "v")
    assert isinstance(value, bytes), value
    return int(value)


def test_sigterm_finishes_work_in_flight_and_closes_streams_with_1001(
    served: tuple[Served, str], frames: list[bytes]
) -> None:
    server, redis_url = served
    http = httpx.Client(base_url=server.url, timeout=WAIT)
    ids = [http.post("/v1/sessions", json=CIRCLE).json()["id"] for _ in range(2)]
    http.close()
    results: list[dict[str, Any]] = []
    url = f"{server.ws_url}/v1/sessions/{ids[0]}/stream"
    with connect(url, open_timeout=WAIT, close_timeout=WAIT) as ws:
        ws.send(frames[0])
        results.append(json.loads(ws.recv(timeout=WAIT)))
        ws.send(frames[1])  # in flight when the signal arrives
        call = RestCall()
        rest = threading.Thread(target=post_frame, args=(server.url, ids[1], frames[2], call))
        rest.start()
        assert call.sent.wait(WAIT)
        server.process.send_signal(signal.SIGTERM)
        closed: ConnectionClosed | None = None
        for _ in range(MAX_RECEIVES):
            try:
                results.append(json.loads(ws.recv(timeout=WAIT)))
            except ConnectionClosed as exc:
                closed = exc
                break
    assert closed is not None, f"no close frame after {MAX_RECEIVES} messages"
    assert closed.rcvd is not None
    assert (closed.rcvd.code, closed.rcvd.reason) == (1001, "server shutting down")
    assert [r["type"] for r in results] == ["frame", "frame"]  # the frame in flight finished
    assert [r["version"] for r in results] == [2, 3]
    with pytest.raises(httpx.ConnectError):  # it stopped listening before closing streams
        httpx.get(f"{server.url}/healthz", timeout=WAIT)

    rest.join(WAIT)
    assert not rest.is_alive()
    assert call.error is None, repr(call.error)
    assert call.status == 200, call.body
    assert len(call.body["nodes"]) == 256
    assert server.process.wait(timeout=WAIT) == 0
    log = server.log.read_text(errors="replace")
    assert "Traceback" not in log
    assert "ERROR" not in log
    if redis_url:  # the stream wrote its session through before closing
        assert stored_version(redis_url, ids[0]) == results[-1]["version"]
        assert stored_version(redis_url, ids[1]) == call.body["version"]
