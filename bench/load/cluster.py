"""Processes of the load benchmark: a throwaway Redis and ``efdm serve`` replicas.

Everything listens on 127.0.0.1 on free ports and is always stopped when its
block ends (SIGTERM: the replicas shut down gracefully, then killed if they
linger).  :func:`redis_counters` reads the Redis ``INFO`` counters the report
divides by the frames tracked.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import redis

from _service_server import HOST, START_TIMEOUT, STOP_TIMEOUT, Server, free_port

REPO = Path(__file__).resolve().parent.parent


@dataclass(frozen=True, slots=True)
class RedisProcess:
    """A running ``redis-server``: its process id and ``redis://`` URL."""

    pid: int
    url: str


@dataclass(slots=True)
class Replicas:
    """Running ``efdm serve`` processes, and their exit codes once stopped."""

    servers: list[Server]
    exit_codes: list[int | None] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class RedisCounters:
    """Cumulative Redis counters at one moment (``INFO everything``).

    Attributes
    ----------
    commands : int
        ``total_commands_processed`` (commands run inside Lua scripts included).
    replies : int
        ``total_writes_processed``: reply writes, about one per client round trip.
    cpu_seconds : float
        ``used_cpu_user + used_cpu_sys`` of the server.
    calls : dict of str to int
        Calls per command (``INFO commandstats``).
    """

    commands: int
    replies: int
    cpu_seconds: float
    calls: dict[str, int]


def _stop(process: subprocess.Popen[bytes]) -> int | None:
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=STOP_TIMEOUT)
    return process.returncode


@contextlib.contextmanager
def running_redis() -> Iterator[RedisProcess]:
    """A ``redis-server`` without persistence on a free loopback port, for the block.

    Raises
    ------
    RuntimeError
        If ``redis-server`` is not installed or does not answer ``PING``.
    """
    binary = shutil.which("redis-server")
    if binary is None:
        raise RuntimeError("redis-server is not installed (Debian package redis-server)")
    port = free_port()
    command = [
        binary, "--port", str(port), "--bind", HOST, "--save", "", "--appendonly", "no",
        "--protected-mode", "yes",
    ]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        url = f"redis://{HOST}:{port}/0"
        deadline = time.monotonic() + 10.0
        with redis.Redis.from_url(url, socket_timeout=1.0) as client:
            while True:
                with contextlib.suppress(redis.RedisError):
                    if client.ping():
                        break
                if time.monotonic() > deadline or process.poll() is not None:
                    raise RuntimeError("redis-server did not start")
                time.sleep(0.02)
        yield RedisProcess(process.pid, url)
    finally:
        _stop(process)


def redis_counters(client: redis.Redis) -> RedisCounters:
    """The Redis counters now (one ``INFO everything`` command on ``client``)."""
    info: dict[str, Any] = client.info("everything")
    calls = {
        key.removeprefix("cmdstat_"): int(value["calls"])
        for key, value in info.items()
        if key.startswith("cmdstat_") and isinstance(value, dict)
    }
    return RedisCounters(
        int(info["total_commands_processed"]),
        int(info["total_writes_processed"]),
        float(info["used_cpu_user"]) + float(info["used_cpu_sys"]),
        calls,
    )


def difference(after: RedisCounters, before: RedisCounters) -> RedisCounters:
    """The counters from ``before`` to ``after`` (commands that ran: calls > 0)."""
    calls = {name: n - before.calls.get(name, 0) for name, n in after.calls.items()}
    return RedisCounters(
        after.commands - before.commands,
        after.replies - before.replies,
        after.cpu_seconds - before.cpu_seconds,
        {name: n for name, n in calls.items() if n > 0},
    )


def counters_overhead(client: redis.Redis) -> RedisCounters:
    """What reading the counters itself adds: two readings with nothing in between."""
    first = redis_counters(client)
    return difference(redis_counters(client), first)


def _tail(path: Path, size: int = 2000) -> str:
    try:
        return path.read_bytes()[-size:].decode(errors="replace")
    except OSError:
        return ""


def _wait_healthy(process: subprocess.Popen[bytes], url: str, log_path: Path) -> None:
    deadline = time.monotonic() + START_TIMEOUT
    with httpx.Client(base_url=url, timeout=2.0) as client:
        while time.monotonic() < deadline:
            if process.poll() is not None:
                raise RuntimeError(f"efdm serve exited ({process.returncode}): {_tail(log_path)}")
            with contextlib.suppress(httpx.HTTPError):
                if client.get("/readyz").status_code == 200:
                    return
            time.sleep(0.05)
    raise RuntimeError(f"efdm serve not ready within {START_TIMEOUT:.0f} s: {_tail(log_path)}")


@contextlib.contextmanager
def running_replicas(count: int, env: Mapping[str, str]) -> Iterator[Replicas]:
    """``count`` processes of ``python -m engine.cli serve`` with ``env``, for the block.

    They start together; each must answer ``/readyz`` (its store reachable).
    Their output goes to temporary files, quoted when one fails to start.
    On exit they get SIGTERM; :attr:`Replicas.exit_codes` records how they ended.
    """
    base = {**os.environ, "EFDM_LOG_LEVEL": "warning", "EFDM_HOST": HOST, **env}
    with contextlib.ExitStack() as stack:
        folder = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="efdm-load-")))
        started: list[tuple[subprocess.Popen[bytes], int, Path]] = []
        replicas = Replicas([])

        def stop_all() -> None:
            replicas.exit_codes = [_stop(process) for process, _, _ in started]

        stack.callback(stop_all)
        start = time.perf_counter()
        for i in range(count):
            port = free_port()
            log_path = folder / f"replica{i}.log"
            sink: Any = stack.enter_context(log_path.open("wb"))
            command = [sys.executable, "-m", "engine.cli", "serve", "--port", str(port)]
            process = subprocess.Popen(command, cwd=REPO, env=base, stdout=sink, stderr=sink)
            started.append((process, port, log_path))
        for process, port, log_path in started:
            url = f"http://{HOST}:{port}"
            _wait_healthy(process, url, log_path)
            seconds = time.perf_counter() - start
            replicas.servers.append(Server(process.pid, url, f"ws://{HOST}:{port}", seconds))
        yield replicas
