"""Resident memory of ``efdm serve`` after many sessions were created, fed and deleted.

``python -m bench.serving.churn [SESSIONS] [--wait SECONDS]`` starts ``efdm serve`` (in-memory
store) on a free port, warms it with five sessions, notes its resident size (idle), then
creates ``SESSIONS`` sessions (default 1,000) from 16 client threads, sends each four
640 x 480 JPEG frames, deletes them all, waits ``--wait`` seconds (default 8: the server
trims its heap :data:`service.memory.TRIM_AFTER` seconds after sessions end) and prints the
resident size with all of them alive and after. Linux only (reads ``/proc``).
"""

from __future__ import annotations

import argparse
import signal
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import httpx
import numpy as np

THREADS = 16
"""Client threads: enough to keep the server's worker threads (and glibc's arenas) busy."""
FRAMES = 4
"""Frames per session: each keeps a tracker's previous frame and models."""


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _resident_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS"):
            return int(line.split()[1]) / 1024
    raise RuntimeError("no VmRSS")


def _frames() -> list[bytes]:
    rng = np.random.default_rng(0)
    out = []
    for i in range(FRAMES):
        image = cv2.GaussianBlur(rng.integers(60, 200, (480, 640, 3), dtype=np.uint8), (0, 0), 2)
        cv2.circle(image, (320 + 3 * i, 240), 60, (40, 40, 220), -1)
        out.append(cv2.imencode(".jpg", image)[1].tobytes())
    return out


def churn(url: str, sessions: int, frames: list[bytes], pid: int) -> float:
    """Create, feed and delete ``sessions`` sessions; the resident MB with all of them alive."""
    clients = [httpx.Client(base_url=url, timeout=60) for _ in range(THREADS)]
    circle = {"circle": {"center": [320, 240], "radius": 60}}

    def create(i: int) -> str:
        sid: str = clients[i % THREADS].post("/v1/sessions", json=circle).json()["id"]
        return sid

    def feed(item: tuple[int, str]) -> None:
        i, sid = item
        for data in frames:
            reply = clients[i % THREADS].post(
                f"/v1/sessions/{sid}/frames", content=data, headers={"content-type": "image/jpeg"}
            )
            reply.raise_for_status()

    def delete(item: tuple[int, str]) -> None:
        clients[item[0] % THREADS].delete(f"/v1/sessions/{item[1]}").raise_for_status()

    with ThreadPoolExecutor(THREADS) as pool:
        ids = list(enumerate(pool.map(create, range(sessions))))
        list(pool.map(feed, ids))
        peak = _resident_mb(pid)
        list(pool.map(delete, ids))
    for client in clients:
        client.close()
    return peak


def main() -> int:
    """Run the churn and print idle, peak and after, in MB."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sessions", nargs="?", type=int, default=1000)
    parser.add_argument("--wait", type=float, default=8.0)
    args = parser.parse_args()
    if not sys.platform.startswith("linux"):
        print("bench.serving.churn reads /proc: Linux only", file=sys.stderr)
        return 2
    port = _free_port()
    efdm = Path(sys.executable).with_name("efdm")
    server = subprocess.Popen(
        [str(efdm), "serve", "--port", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    url = f"http://127.0.0.1:{port}"
    try:
        for _ in range(150):
            try:
                httpx.get(url + "/healthz", timeout=1.0)
                break
            except httpx.HTTPError:
                time.sleep(0.2)
        frames = _frames()
        churn(url, 5, frames, server.pid)
        time.sleep(args.wait)
        idle = _resident_mb(server.pid)
        peak = churn(url, args.sessions, frames, server.pid)
        time.sleep(args.wait)
        after = _resident_mb(server.pid)
    finally:
        server.send_signal(signal.SIGINT)
        server.wait(30)
    print("| resident memory of efdm serve | MB | x idle |")
    print("|---|---|---|")
    print(f"| idle (after 5 sessions) | {idle:.0f} | 1.00 |")
    print(f"| {args.sessions} sessions alive, fed | {peak:.0f} | {peak / idle:.2f} |")
    print(f"| {args.wait:g} s after all were deleted | {after:.0f} | {after / idle:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
