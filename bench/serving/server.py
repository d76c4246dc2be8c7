"""A real ``efdm serve`` process on loopback for the service benchmark.

:func:`running_server` starts it on a free 127.0.0.1 port, waits for
``/healthz`` and always terminates it (then kills it if it lingers).
:func:`cpu_seconds` reads a process's CPU time from ``/proc`` so the report
can say how much server CPU one frame or request costs.
"""

from __future__ import annotations

import contextlib
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import httpx

REPO = Path(__file__).resolve().parent.parent
HOST = "127.0.0.1"
START_TIMEOUT = 60.0
STOP_TIMEOUT = 10.0


@dataclass(frozen=True, slots=True)
class Server:
    """A running service.

    Attributes
    ----------
    pid : int
        Process id of the server.
    url, ws_url : str
        ``http://127.0.0.1:PORT`` and ``ws://127.0.0.1:PORT``.
    start_seconds : float
        From spawning to the first healthy ``/healthz``.
    """

    pid: int
    url: str
    ws_url: str
    start_seconds: float


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket() as s:
        s.bind((HOST, 0))
        port: int = s.getsockname()[1]
        return port


def _tail(path: Path, size: int = 2000) -> str:
    try:
        return path.read_bytes()[-size:].decode(errors="replace")
    except OSError:
        return ""


def _wait_healthy(
    process: subprocess.Popen[bytes], url: str, timeout: float, log_path: Path
) -> None:
    deadline = time.monotonic() + timeout
    with httpx.Client(base_url=url, timeout=2.0) as client:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                raise RuntimeError(
                    f"efdm serve exited with code {process.returncode}: {_tail(log_path)}"
                )
            with contextlib.suppress(httpx.HTTPError):
                if client.get("/healthz").status_code == 200:
                    return
            time.sleep(0.05)
    raise RuntimeError(f"efdm serve not healthy within {timeout:.0f} s: {_tail(log_path)}")


def _stop(process: subprocess.Popen[bytes]) -> None:
    if process.poll() is not None:
        return
    process.terminate()
    try:
        process.wait(timeout=STOP_TIMEOUT)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=STOP_TIMEOUT)


@contextlib.contextmanager
def running_server() -> Iterator[Server]:
    """Run ``python -m engine.cli serve`` on a free loopback port for the block.

    The server's output goes to a temporary file, quoted when it fails to
    start.  The process is terminated when the block ends, however it ends.
    """
    port = free_port()
    env = {**os.environ, "EFDM_LOG_LEVEL": "warning", "EFDM_HOST": HOST}
    command = [sys.executable, "-m", "engine.cli", "serve", "--host", HOST, "--port", str(port)]
    with contextlib.ExitStack() as stack:
        log_path = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="efdm-serve-")))
        log_path /= "server.log"
        sink: Any = stack.enter_context(log_path.open("wb"))
        start = time.perf_counter()
        process = subprocess.Popen(command, cwd=REPO, env=env, stdout=sink, stderr=sink)
        stack.callback(_stop, process)
        url = f"http://{HOST}:{port}"
        _wait_healthy(process, url, START_TIMEOUT, log_path)
        yield Server(process.pid, url, f"ws://{HOST}:{port}", time.perf_counter() - start)


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of a process, all threads (NaN where unknown)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text(encoding="ascii").rsplit(")", 1)[1].split()
        ticks = os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return float("nan")
    return (int(fields[11]) + int(fields[12])) / ticks


def create_session(client: httpx.Client, nodes: list[list[float]]) -> str:
    """A new closed-contour session starting from ``nodes``; returns its id."""
    response = client.post("/v1/sessions", json={"nodes": nodes})
    response.raise_for_status()
    session_id: str = response.json()["id"]
    return session_id


def create_circle_session(client: httpx.Client, count: int) -> str:
    """A new session with a circle of ``count`` nodes (for ``/forces``)."""
    spec = {"circle": {"center": [320.0, 240.0], "radius": 100.0, "count": count}}
    response = client.post("/v1/sessions", json=spec)
    response.raise_for_status()
    session_id: str = response.json()["id"]
    return session_id


def frame_seconds(client: httpx.Client, transport: str) -> tuple[float, int]:
    """The server's ``efdm_frame_seconds`` sum and count for ``transport`` (from /metrics).

    That histogram times a frame inside the handler: lease, decode, the worker
    thread and the tracker step.  (0, 0) until the server has observed one.
    """
    text = client.get("/metrics").text
    found: dict[str, float] = {}
    for part in ("sum", "count"):
        pattern = rf'^efdm_frame_seconds_{part}\{{[^}}]*transport="{transport}"[^}}]*\}} (\S+)$'
        match = re.search(pattern, text, re.MULTILINE)
        if match is not None:
            found[part] = float(match.group(1))
    if len(found) != 2:
        return 0.0, 0
    return found["sum"], int(found["count"])
