"""Two ``efdm serve`` processes sharing one Redis: the scale-out guarantees."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

import httpx
import numpy as np
import pytest
from websockets.sync.client import connect

from tests.service.conftest import RedisServer, disc_frame, free_port

CIRCLE = {"circle": {"center": [160, 120], "radius": 40, "count": 64}}
JPEG = {"content-type": "image/jpeg"}


class Replica:
    """One ``efdm serve`` process."""

    def __init__(self, redis_url: str) -> None:
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}"
        self.ws = f"ws://127.0.0.1:{self.port}"
        env = {**os.environ, "EFDM_REDIS_URL": redis_url, "EFDM_LOG_LEVEL": "critical"}
        self.process = subprocess.Popen(
            [sys.executable, "-m", "efdm_cli", "serve", "--port", str(self.port)],
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        for _ in range(600):  # imports and the kernels' warm-up: up to ~60 s
            try:
                if httpx.get(f"{self.url}/healthz", timeout=1).status_code == 200:
                    return
            except httpx.TransportError:
                time.sleep(0.1)
        self.stop()
        raise RuntimeError("replica did not start")

    def stop(self) -> None:
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()


@contextmanager
def replicas(url: str, count: int = 2) -> Iterator[list[Replica]]:
    started: list[Replica] = []
    try:
        for _ in range(count):
            started.append(Replica(url))
        yield started
    finally:
        for r in started:
            r.stop()


@pytest.fixture(scope="module")
def pair(redis_server: RedisServer) -> Iterator[list[Replica]]:
    with replicas(redis_server.url) as two:
        yield two


def test_create_on_one_track_on_the_other_delete_on_the_first(pair: list[Replica]) -> None:
    a, b = pair
    sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
    assert httpx.get(f"{b.url}/v1/sessions/{sid}").status_code == 200
    first = httpx.post(
        f"{b.url}/v1/sessions/{sid}/frames", content=disc_frame(160, 120), headers=JPEG
    )
    second = httpx.post(
        f"{a.url}/v1/sessions/{sid}/frames", content=disc_frame(166, 122), headers=JPEG
    )
    assert first.json()["frame_index"] == 0
    assert second.json()["frame_index"] == 1
    centre = np.mean(second.json()["nodes"], axis=0)
    assert np.hypot(centre[0] - 166, centre[1] - 122) < 2
    assert httpx.delete(f"{a.url}/v1/sessions/{sid}").status_code == 204
    assert httpx.get(f"{b.url}/v1/sessions/{sid}").status_code == 404


def test_concurrent_updates_over_two_replicas_lose_nothing(pair: list[Replica]) -> None:
    a, b = pair
    sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
    outcomes: list[tuple[int, dict[str, object]]] = []
    lock = threading.Lock()

    def update(k: int) -> None:
        target = (a, b)[k % 2]
        forces = np.zeros((64, 2))
        forces[k % 64] = [float(k), 0.0]
        with httpx.Client(timeout=30) as http:
            r = http.post(
                f"{target.url}/v1/sessions/{sid}/forces", json={"forces": forces.tolist()}
            )
        with lock:
            outcomes.append((r.status_code, r.json()))

    threads = [threading.Thread(target=update, args=(k,)) for k in range(100)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    codes = [code for code, _ in outcomes]
    assert set(codes) <= {200, 409, 412}
    successes = [body for code, body in outcomes if code == 200]
    assert successes
    versions = sorted(int(str(body["version"])) for body in successes)
    assert versions == list(range(2, 2 + len(successes)))  # each success exactly +1
    final = httpx.get(f"{b.url}/v1/sessions/{sid}").json()
    assert final["version"] == 1 + len(successes)
    last = next(body for body in successes if body["version"] == final["version"])
    assert final["nodes"] == last["nodes"]  # the stored contour is the last success's


def test_stream_resumes_on_the_other_replica_after_sigkill(redis_server: RedisServer) -> None:
    with replicas(redis_server.url) as (a, b):
        sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
        frames = [disc_frame(160 + 3 * k, 120 + k) for k in range(12)]
        received = []
        with connect(f"{a.ws}/v1/sessions/{sid}/stream") as ws:
            for frame in frames[:6]:
                ws.send(frame)
                received.append(json.loads(ws.recv(timeout=30)))
            a.process.send_signal(signal.SIGKILL)  # no chance to clean up
            a.process.wait(timeout=10)
        last = received[-1]["frame_index"]
        assert last == 5
        session = httpx.get(f"{b.url}/v1/sessions/{sid}").json()
        assert session["frame_index"] == last  # every acknowledged frame was committed
        assert session["nodes"] == received[-1]["nodes"]
        with connect(f"{b.ws}/v1/sessions/{sid}/stream") as ws:
            for k, frame in enumerate(frames[6:], start=6):
                ws.send(frame)
                result = json.loads(ws.recv(timeout=30))
                assert result["frame_index"] == k  # continues where A stopped
        centre = np.mean(result["nodes"], axis=0)
        assert np.hypot(centre[0] - (160 + 3 * 11), centre[1] - (120 + 11)) < 2


def test_redis_down_means_503_and_recovery_without_restart() -> None:
    redis = RedisServer()
    try:
        with replicas(redis.url, count=1) as (a,):
            assert httpx.get(f"{a.url}/readyz").status_code == 200
            redis.stop()
            ready = httpx.get(f"{a.url}/readyz", timeout=5)
            created = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE, timeout=5)
            assert ready.status_code == 503
            assert created.status_code == 503
            assert created.json()["error"]["code"] == "unavailable"
            assert httpx.get(f"{a.url}/healthz").status_code == 200  # alive, just not ready
            redis.process = redis.start()
            for _ in range(50):
                if httpx.get(f"{a.url}/readyz", timeout=5).status_code == 200:
                    break
                time.sleep(0.1)
            sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
            frame = httpx.post(
                f"{a.url}/v1/sessions/{sid}/frames", content=disc_frame(160, 120), headers=JPEG
            )
            assert frame.status_code == 200
    finally:
        redis.stop()


def test_a_second_stream_on_another_replica_takes_over_without_409s(
    redis_server: RedisServer,
) -> None:
    """In Redis mode a second stream got 409 on nearly every frame; now, as in memory,
    the newer stream takes the session over and the older one is closed with 4409."""
    from websockets.exceptions import ConnectionClosedError

    with replicas(redis_server.url) as (a, b):
        sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
        frames = [disc_frame(160 + 2 * k, 120) for k in range(8)]
        with connect(f"{a.ws}/v1/sessions/{sid}/stream") as old:
            old.send(frames[0])
            assert json.loads(old.recv(timeout=30))["frame_index"] == 0
            with connect(f"{b.ws}/v1/sessions/{sid}/stream") as new:
                for k in range(1, 5):
                    new.send(frames[k])
                    result = json.loads(new.recv(timeout=30))
                    assert result["type"] == "frame", result  # never a 409
                    assert result["frame_index"] == k
                old.send(frames[5])
                with pytest.raises(ConnectionClosedError) as closed:
                    old.recv(timeout=30)
                assert closed.value.rcvd is not None
                assert closed.value.rcvd.code == 4409
                assert httpx.get(f"{b.url}/v1/sessions/{sid}").json()["frame_index"] == 4
                new.send(frames[5])
                assert json.loads(new.recv(timeout=30))["frame_index"] == 5


def test_a_stream_frame_refused_during_an_outage_is_never_applied() -> None:
    """Frames answered 503 while Redis was down were committed once it returned."""
    redis = RedisServer()
    try:
        with replicas(redis.url, count=1) as (a,):
            sid = httpx.post(f"{a.url}/v1/sessions", json=CIRCLE).json()["id"]
            with connect(f"{a.ws}/v1/sessions/{sid}/stream") as ws:
                for k in range(3):
                    ws.send(disc_frame(160 + 2 * k, 120))
                    assert json.loads(ws.recv(timeout=30))["frame_index"] == k
                redis.process.send_signal(signal.SIGSTOP)  # unreachable, its data kept
                refused = 0
                for k in range(3, 6):
                    ws.send(disc_frame(160 + 2 * k, 120))
                    answer = json.loads(ws.recv(timeout=30))
                    assert answer["type"] == "error", answer
                    assert answer["error"]["status"] == 503
                    refused += 1
                redis.process.send_signal(signal.SIGCONT)
                for _ in range(50):
                    if httpx.get(f"{a.url}/readyz", timeout=5).status_code == 200:
                        break
                    time.sleep(0.1)
                ws.send(disc_frame(172, 120))
                result = json.loads(ws.recv(timeout=30))
            assert refused == 3
            assert result["frame_index"] == 3  # none of the refused frames was applied
            stored = httpx.get(f"{a.url}/v1/sessions/{sid}").json()
            assert stored["frame_index"] == 3
            assert stored["nodes"] == result["nodes"]
    finally:
        redis.process.send_signal(signal.SIGCONT)
        redis.stop()
