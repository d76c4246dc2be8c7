"""Real ``efdm serve`` processes on loopback, for the service and load benchmarks.

:func:`running_servers` starts them on free 127.0.0.1 ports, waits until each
answers (``/healthz``, or ``/readyz`` when its store must be reachable too) and
always stops them (SIGTERM: a graceful shutdown; SIGKILL if they linger).
Sessions are made with the project's client (:mod:`service.client`);
:func:`frame_seconds` reads the server's own timing of frames from ``/metrics``.
"""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx

from bench.common import REPO
from bench.common.processes import HOST, free_port, stop, tail
from service.client import Client

START_TIMEOUT = 60.0
TIMEOUT = 20.0
"""Seconds for any one request of the benchmarks' clients."""
CIRCLE = ((320.0, 240.0), 100.0)
"""Centre and radius of the ``/forces`` sessions' circles."""


@dataclass(frozen=True, slots=True)
class Server:
    """A running service.

    Attributes
    ----------
    pid : int
        Process id of the server.
    url : str
        ``http://127.0.0.1:PORT`` (the client derives the ``ws://`` URLs).
    start_seconds : float
        From spawning (all the servers started together) to its first ready answer.
    """

    pid: int
    url: str
    start_seconds: float


@dataclass(slots=True)
class Servers:
    """Running ``efdm serve`` processes, and their exit codes once stopped."""

    servers: list[Server]
    exit_codes: list[int | None] = field(default_factory=list)


def _wait_ready(process: subprocess.Popen[bytes], url: str, path: str, log_path: Path) -> None:
    deadline = time.monotonic() + START_TIMEOUT
    with httpx.Client(base_url=url, timeout=2.0) as client:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                raise RuntimeError(f"efdm serve exited ({process.returncode}): {tail(log_path)}")
            with contextlib.suppress(httpx.HTTPError):
                if client.get(path).status_code == 200:
                    return
            time.sleep(0.05)
    raise RuntimeError(f"efdm serve not ready within {START_TIMEOUT:.0f} s: {tail(log_path)}")


@contextlib.contextmanager
def running_servers(
    count: int = 1, env: Mapping[str, str] | None = None, ready: str = "/healthz"
) -> Iterator[Servers]:
    """``count`` processes of ``python -m efdm_cli serve`` with ``env``, for the block.

    They start together; each must answer ``ready`` with 200 (``/readyz``:
    its store reachable).  Their output goes to temporary files, quoted when
    one fails to start.  However the block ends they get SIGTERM;
    :attr:`Servers.exit_codes` records how they ended.
    """
    base = {**os.environ, "EFDM_LOG_LEVEL": "warning", "EFDM_HOST": HOST, **(env or {})}
    with contextlib.ExitStack() as stack:
        folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="efdm-serve-")))
        started: list[tuple[subprocess.Popen[bytes], int, Path]] = []
        running = Servers([])

        def stop_all() -> None:
            running.exit_codes = [stop(process) for process, _, _ in started]

        stack.callback(stop_all)
        start = time.perf_counter()
        for i in range(count):
            port = free_port()
            log_path = folder / f"server{i}.log"
            sink: Any = stack.enter_context(log_path.open("wb"))
            command = [
                sys.executable,
                "-m",
                "efdm_cli",
                "serve",
                "--host",
                HOST,
                "--port",
                str(port),
            ]
            process = subprocess.Popen(command, cwd=REPO, env=base, stdout=sink, stderr=sink)
            started.append((process, port, log_path))
        for process, port, log_path in started:
            url = f"http://{HOST}:{port}"
            _wait_ready(process, url, ready, log_path)
            running.servers.append(Server(process.pid, url, time.perf_counter() - start))
        yield running


def forces_paths(server: Server, count: int, nodes: int) -> list[str]:
    """``/forces`` paths of ``count`` new sessions, each a circle of ``nodes`` nodes."""
    with Client(server.url, timeout=TIMEOUT) as client:
        return [
            f"/v1/sessions/{client.create_session(circle=(*CIRCLE, nodes)).id}/forces"
            for _ in range(count)
        ]


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
