"""REST rows of the service benchmark: ``/frames`` and ``/forces``.

``/frames`` goes through the project's client (:meth:`service.client.Client.track_frame`),
one session, each frame after the previous answer.  ``/forces`` measures how
many requests the server answers, with the load generator on the same two
cores: the sessions are made with the client, but the timed requests POST one
pre-encoded body over plain ``httpx`` (the bytes ``wrk`` sends too), because
the client's own encoding and parsing of 256 forces per request would take
CPU from the server and lower the rate it shows.  Concurrent ``/forces``
clients are threads, each with its own keep-alive connection and session,
released together by a barrier.  Every loop stops at its request count or its
deadline, whichever comes first.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import httpx

from bench.serving.data import JpegClip
from bench.serving.server import TIMEOUT, Server, forces_paths
from bench.serving.stats import FrameRun, Measurement, handler_timed, metered, together
from service.client import ApiError, Client, FrameResult

JSON = {"content-type": "application/json"}


def rest_frames(server: Server, clip: JpegClip, name: str, seconds: float) -> FrameRun:
    """POST every frame of ``clip`` to one session, each after the previous answer."""
    row = Measurement(name, "frames")
    run = FrameRun(row)
    deadline = time.monotonic() + seconds
    with Client(server.url, timeout=TIMEOUT) as client:
        session = client.create_session(clip.nodes)
        with together(handler_timed(row, server.url, "rest"), metered(row, [server.pid])):
            start = time.perf_counter()
            for data in clip.frames:
                if time.monotonic() > deadline:
                    break
                t0 = time.perf_counter()
                row.sent += 1
                result: FrameResult | None
                try:
                    result = client.track_frame(session, data)
                except ApiError:
                    result = None
                row.latencies_ms.append((time.perf_counter() - t0) * 1e3)
                if result is None:
                    row.errors += 1
                    continue
                row.items += 1
                row.server_ms.append(result.elapsed_ms)
                run.nodes.append(result.nodes)
            row.seconds = time.perf_counter() - start
    return run


@dataclass(frozen=True, slots=True)
class ForcesLoad:
    """A ``/forces`` load: concurrent clients, requests each, the body and the time limit."""

    clients: int
    requests: int
    warmup: int
    body: bytes
    seconds: float


def _forces_client(
    client: httpx.Client, path: str, load: ForcesLoad, start: threading.Barrier, out: Measurement
) -> None:
    for _ in range(load.warmup):
        client.post(path, content=load.body, headers=JSON)
    start.wait(timeout=TIMEOUT)
    deadline = time.monotonic() + load.seconds
    for _ in range(load.requests):
        if time.monotonic() > deadline:
            break
        t0 = time.perf_counter()
        response = client.post(path, content=load.body, headers=JSON)
        out.latencies_ms.append((time.perf_counter() - t0) * 1e3)
        out.sent += 1
        if response.status_code == 200:
            out.items += 1
        else:
            out.errors += 1


def rest_forces(server: Server, load: ForcesLoad, nodes: int, name: str) -> Measurement:
    """``load.clients`` threads, each POSTing ``/forces`` to its own session; wall-clock rate."""
    paths = forces_paths(server, load.clients, nodes)
    clients = [httpx.Client(base_url=server.url, timeout=TIMEOUT) for _ in paths]
    rows = [Measurement(name, "requests") for _ in clients]
    barrier = threading.Barrier(load.clients + 1)
    total = Measurement(name, "requests", clients=load.clients)
    try:
        threads = [
            threading.Thread(target=_forces_client, args=(c, p, load, barrier, r), daemon=True)
            for c, p, r in zip(clients, paths, rows, strict=True)
        ]
        for thread in threads:
            thread.start()
        barrier.wait(timeout=TIMEOUT)
        with metered(total, [server.pid]):
            start = time.perf_counter()
            for thread in threads:
                thread.join(timeout=load.seconds + TIMEOUT)
            wall = time.perf_counter() - start
    finally:
        for client in clients:
            client.close()
    for row in rows:
        total.add(row)
    total.seconds = wall
    return total
