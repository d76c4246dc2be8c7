"""Smoke test of a running service container (``docker/test-container.sh``; not collected).

``python -m tests.deploy.container_smoke http://127.0.0.1:PORT`` waits for ``/healthz``, then
creates a session, tracks three JPEG frames of a moving disc over REST and one over the
WebSocket, and checks readiness, metrics, the demo page and deletion. Exit status 0 on success.

With ``--replica URL`` (repeated), PORT is the load balancer in front of those replicas
(docker/compose.yaml's topology): the frame counts are summed over the replicas, a session
created through the balancer is visible on every replica (shared Redis), and each session's
frames all land on one replica (nginx's hash by session id) while sessions spread over all.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import time
import traceback

import cv2
import httpx
import numpy as np
from websockets.sync.client import connect

RADIUS = 40
CENTRES = [(150.0, 120.0), (156.0, 122.0), (162.0, 124.0), (168.0, 126.0)]


def disc_jpeg(cx: float, cy: float, *, shape: tuple[int, int] = (240, 320)) -> bytes:
    """A JPEG of a red disc on a light, textured background (``[x, y]`` centre)."""
    rng = np.random.default_rng(1)
    img = cv2.GaussianBlur(rng.integers(150, 230, (*shape, 3), dtype=np.uint8), (0, 0), 2)
    img = np.ascontiguousarray(img)
    centre = (round(cx * 16), round(cy * 16))
    cv2.circle(img, centre, RADIUS * 16, (40, 40, 170), -1, cv2.LINE_AA, 4)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 92])
    if not ok:
        raise RuntimeError("JPEG encoding failed")
    return data.tobytes()


def wait_healthy(http: httpx.Client, timeout: float) -> float:
    """Seconds until ``/healthz`` answered 200; raises after ``timeout``."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        try:
            if http.get("/healthz", timeout=2).status_code == 200:
                return time.monotonic() - start
        except httpx.TransportError:
            pass
        time.sleep(0.25)
    raise AssertionError(f"/healthz did not answer within {timeout:.0f} s")


def frames_processed(http: httpx.Client, url: str) -> dict[str, float]:
    """``efdm_frames_processed_total`` by transport, from ``url``/metrics."""
    text = http.get(f"{url}/metrics").text
    found = re.findall(r'^efdm_frames_processed_total\{transport="(\w+)"\} (\S+)$', text, re.M)
    return {transport: float(value) for transport, value in found}


def check_frame(result: dict[str, object], index: int, count: int) -> tuple[float, float]:
    """Validate one frame result; return the contour's centroid."""
    assert result["frame_index"] == index, result
    nodes = np.asarray(result["nodes"], dtype=float)
    assert nodes.shape == (count, 2), nodes.shape
    assert np.isfinite(nodes).all()
    confidence = result["confidence"]
    assert isinstance(confidence, float | int)
    assert 0.0 <= confidence <= 1.0
    cx, cy = nodes.mean(axis=0)
    return float(cx), float(cy)


def run(url: str, timeout: float, replicas: list[str]) -> None:
    """All the checks against the service at ``url`` (a balancer when ``replicas``)."""
    ws_url = "ws" + url.removeprefix("http")
    with httpx.Client(base_url=url, timeout=30) as http:
        waited = wait_healthy(http, timeout)
        print(f"   /healthz after {waited:.1f} s")
        ready = http.get("/readyz")
        assert ready.status_code == 200, ready.text
        assert ready.json() == {"status": "ready"}

        page = http.get("/")
        assert page.status_code == 200, (
            f"GET / -> {page.status_code}: the demo page is not in the installed package "
            "(service/static/* must be package data of the wheel)"
        )
        assert "text/html" in page.headers["content-type"]

        count = 64
        circle = {"center": list(CENTRES[0]), "radius": RADIUS, "count": count}
        created = http.post("/v1/sessions", json={"circle": circle})
        assert created.status_code == 201, created.text
        session = created.json()
        sid = session["id"]
        assert session["frame_index"] == -1

        version = session["version"]
        for i, (x, y) in enumerate(CENTRES[:3]):
            reply = http.post(
                f"/v1/sessions/{sid}/frames",
                content=disc_jpeg(x, y),
                headers={"Content-Type": "image/jpeg"},
            )
            assert reply.status_code == 200, reply.text
            result = reply.json()
            cx, cy = check_frame(result, i, count)
            assert result["version"] > version
            version = result["version"]
            error = math.hypot(cx - x, cy - y)
            print(f"   frame {i}: centroid ({cx:.1f}, {cy:.1f}), disc ({x:.0f}, {y:.0f}), "
                  f"error {error:.2f} px, confidence {result['confidence']:.3f}, "
                  f"{result['elapsed_ms']:.1f} ms")  # fmt: skip
            assert error < 3.0, f"frame {i}: the contour did not follow the disc"

        with connect(f"{ws_url}/v1/sessions/{sid}/stream", open_timeout=10) as ws:
            x, y = CENTRES[3]
            ws.send(disc_jpeg(x, y))
            message = json.loads(ws.recv(timeout=30))
            assert message["type"] == "frame", message
            cx, cy = check_frame(message, 3, count)
            assert math.hypot(cx - x, cy - y) < 3.0, "WebSocket frame: the contour is off"
            ws.send(json.dumps({"ping": 7}))
            assert json.loads(ws.recv(timeout=10)) == {"type": "pong", "pong": 7}
        print("   WebSocket frame and ping ok")

        metrics = http.get("/metrics")
        assert metrics.status_code == 200
        if not replicas:
            assert frames_processed(http, url) == {"rest": 3.0, "websocket": 1.0}
        else:
            counts = [frames_processed(http, r) for r in replicas]
            print(f"   frames by replica: {counts}")
            assert {"rest": 3.0, "websocket": 1.0} in counts, "the session's frames were split"
            for r in replicas:  # one Redis behind every replica
                assert http.get(f"{r}/v1/sessions/{sid}").json()["version"] == session_version(
                    http, url, sid
                )
            check_affinity(http, replicas, count)
        assert http.delete(f"/v1/sessions/{sid}").status_code == 204
        assert http.get(f"/v1/sessions/{sid}").status_code == 404
        for r in replicas:
            assert http.get(f"{r}/v1/sessions/{sid}").status_code == 404


def session_version(http: httpx.Client, url: str, sid: str) -> int:
    """The session's version, read at ``url``."""
    reply = http.get(f"{url}/v1/sessions/{sid}")
    assert reply.status_code == 200, reply.text
    version: int = reply.json()["version"]
    return version


def check_affinity(http: httpx.Client, replicas: list[str], count: int, sessions: int = 12) -> None:
    """Through the balancer: each session sticks to one replica; sessions use every replica."""

    def totals() -> list[float]:
        return [sum(frames_processed(http, r).values()) for r in replicas]

    used: set[int] = set()
    circle = {"center": list(CENTRES[0]), "radius": RADIUS, "count": count}
    for _ in range(sessions):
        sid = http.post("/v1/sessions", json={"circle": circle}).json()["id"]
        served = []
        for x, y in CENTRES[:2]:
            before = totals()
            reply = http.post(
                f"/v1/sessions/{sid}/frames",
                content=disc_jpeg(x, y),
                headers={"Content-Type": "image/jpeg"},
            )
            assert reply.status_code == 200, reply.text
            after = totals()
            served.append([n for n, (a, b) in enumerate(zip(before, after, strict=True)) if b > a])
        assert served[0] == served[1], f"session {sid}: frames on replicas {served}"
        assert len(served[0]) == 1
        used.add(served[0][0])
        assert http.delete(f"/v1/sessions/{sid}").status_code == 204
    print(f"   affinity: {sessions} sessions, each on one replica, {len(used)} replicas used")
    assert used == set(range(len(replicas))), f"replicas used: {sorted(used)}"


def main(argv: list[str] | None = None) -> int:
    """Command line: the service's base URL."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("url", help="e.g. http://127.0.0.1:8000")
    parser.add_argument("--timeout", type=float, default=180.0, help="seconds to wait for start")
    parser.add_argument(
        "--replica", action="append", default=[], help="a replica behind the balancer at url"
    )
    args = parser.parse_args(argv)
    try:
        run(args.url.rstrip("/"), args.timeout, [r.rstrip("/") for r in args.replica])
    except (AssertionError, httpx.HTTPError, OSError):
        traceback.print_exc()
        print("container smoke test failed", file=sys.stderr)
        return 1
    print("   smoke test passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
