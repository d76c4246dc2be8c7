"""Shared fixtures: settings, the app in-process, and a real server on loopback."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import cv2
import httpx
import numpy as np
import pytest
import uvicorn
from fastapi.testclient import TestClient

from service.app import create_app
from service.settings import Settings


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def disc_frame(cx: float, cy: float, *, r: int = 40, shape: tuple[int, int] = (240, 320)) -> bytes:
    """A JPEG of a red disc on a light textured background (BGR, ``[x, y]`` centre)."""
    rng = np.random.default_rng(1)
    img = cv2.GaussianBlur(rng.integers(150, 230, (*shape, 3), dtype=np.uint8), (0, 0), 2)
    img = np.ascontiguousarray(img)
    cv2.circle(img, (round(cx * 16), round(cy * 16)), r * 16, (40, 40, 170), -1, cv2.LINE_AA, 4)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 92])
    assert ok
    return data.tobytes()


@pytest.fixture
def settings() -> Settings:
    """Embedded defaults, small limits where tests need them."""
    return Settings(max_sessions=50, session_ttl_seconds=600)


@pytest.fixture
def client(settings: Settings) -> Iterator[TestClient]:
    """The app in-process (lifespan run), as a Starlette TestClient."""
    with TestClient(create_app(settings)) as c:
        yield c


@dataclass
class LiveServer:
    """A real uvicorn server on 127.0.0.1."""

    url: str
    ws_url: str
    settings: Settings


def _serve(settings: Settings) -> Iterator[LiveServer]:
    port = free_port()
    config = uvicorn.Config(
        create_app(settings), host="127.0.0.1", port=port, log_level="warning", lifespan="on"
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 30
    while not server.started:
        if time.monotonic() > deadline or not thread.is_alive():
            raise RuntimeError("uvicorn did not start")
        time.sleep(0.02)
    try:
        yield LiveServer(f"http://127.0.0.1:{port}", f"ws://127.0.0.1:{port}", settings)
    finally:
        server.should_exit = True
        thread.join(timeout=10)


@pytest.fixture
def live_server(settings: Settings) -> Iterator[LiveServer]:
    """A real server (uvicorn, loopback) with the test settings."""
    yield from _serve(settings)


class RedisServer:
    """A throwaway ``redis-server`` on a free loopback port (no persistence)."""

    def __init__(self) -> None:
        import shutil
        import subprocess

        binary = shutil.which("redis-server")
        if binary is None:
            message = "redis-server is not installed (Debian package redis-server)"
            if os.environ.get("CI"):
                pytest.fail(message)  # CI installs it: never skip there
            pytest.skip(message)
        self.port = free_port()
        self.url = f"redis://127.0.0.1:{self.port}/0"
        self._args = [
            binary, "--port", str(self.port), "--bind", "127.0.0.1",
            "--save", "", "--appendonly", "no", "--protected-mode", "yes",
        ]  # fmt: skip
        self._popen = subprocess.Popen
        self.process = self.start()

    def start(self) -> Any:
        """Start (or restart) the server and wait until it answers."""
        import subprocess

        process = self._popen(self._args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            with socket.socket() as s:
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return process
            time.sleep(0.02)
        process.kill()
        raise RuntimeError("redis-server did not start")

    def stop(self) -> None:
        """Stop the server (data is lost: no persistence)."""
        self.process.terminate()
        self.process.wait(timeout=10)

    def restart(self) -> None:
        """Stop and start again on the same port."""
        self.stop()
        self.process = self.start()


@pytest.fixture(scope="session")
def redis_server() -> Iterator[RedisServer]:
    """One redis-server for the test session."""
    server = RedisServer()
    try:
        yield server
    finally:
        server.stop()


@dataclass
class ServeRun:
    """What an ``efdm serve`` process printed and how it ended (filled when it stops)."""

    url: str
    out: str = ""
    err: str = ""
    returncode: int | None = None


@contextlib.contextmanager
def efdm_serve(**env: str) -> Iterator[ServeRun]:
    """``efdm serve`` as a process on a free port with ``EFDM_*`` ``env``; stopped by SIGINT."""
    port = free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", "efdm_cli", "serve", "--port", str(port)],
        env={**os.environ, **env},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    run = ServeRun(f"http://127.0.0.1:{port}")
    try:
        for _ in range(300):  # up to ~30 s for imports and the solver's warm-up
            try:
                if httpx.get(f"{run.url}/healthz", timeout=1).status_code == 200:
                    break
            except httpx.TransportError:
                time.sleep(0.1)
        else:
            raise AssertionError("efdm serve did not answer /healthz")
        yield run
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            out, err = proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
        run.out, run.err, run.returncode = out.decode(), err.decode(), proc.returncode
