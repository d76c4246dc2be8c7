"""REST clients for the service benchmark: ``/frames`` and ``/forces`` over httpx.

Each client keeps one keep-alive connection (``httpx.Client``).  Concurrent
``/forces`` clients are threads, each with its own connection and session,
released together by a barrier.  Every loop stops at its request count or
its deadline, whichever comes first.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import httpx

from _service_data import JpegClip
from _service_server import Server, create_circle_session, create_session
from _service_stats import FrameRun, Measurement, handler_timed, metered

TIMEOUT = 20.0
JPEG = {"content-type": "image/jpeg"}
JSON = {"content-type": "application/json"}


def rest_frames(server: Server, clip: JpegClip, name: str, deadline: float) -> FrameRun:
    """POST every frame of ``clip`` to one session, each after the previous answer."""
    row = Measurement(name, "frames")
    run = FrameRun(row)
    with httpx.Client(base_url=server.url, timeout=TIMEOUT) as client:
        path = f"/v1/sessions/{create_session(client, clip.nodes)}/frames"
        with handler_timed(row, server.url, "rest"), metered(row, server.pid):
            _post_frames(client, path, clip, deadline, run)
    return run


def _post_frames(
    client: httpx.Client, path: str, clip: JpegClip, deadline: float, run: FrameRun
) -> None:
    row = run.measurement
    start = time.perf_counter()
    for data in clip.frames:
        if time.monotonic() > deadline:
            break
        t0 = time.perf_counter()
        response = client.post(path, content=data, headers=JPEG)
        row.latencies_ms.append((time.perf_counter() - t0) * 1e3)
        row.sent += 1
        if response.status_code != 200:
            row.errors += 1
            continue
        body = response.json()
        row.items += 1
        row.server_ms.append(float(body["elapsed_ms"]))
        run.nodes.append(body["nodes"])
    row.seconds = time.perf_counter() - start


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
    clients = [httpx.Client(base_url=server.url, timeout=TIMEOUT) for _ in range(load.clients)]
    rows = [Measurement(name, "requests") for _ in clients]
    barrier = threading.Barrier(load.clients + 1)
    total = Measurement(name, "requests", clients=load.clients)
    try:
        paths = [f"/v1/sessions/{create_circle_session(c, nodes)}/forces" for c in clients]
        threads = [
            threading.Thread(target=_forces_client, args=(c, p, load, barrier, r), daemon=True)
            for c, p, r in zip(clients, paths, rows, strict=True)
        ]
        for thread in threads:
            thread.start()
        barrier.wait(timeout=TIMEOUT)
        with metered(total, server.pid):
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
