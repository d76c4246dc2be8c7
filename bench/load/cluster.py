"""The load benchmark's Redis: a throwaway ``redis-server`` and its counters.

It listens on 127.0.0.1 on a free port and is always stopped when its block
ends; the ``efdm serve`` replicas come from :func:`bench.serving.server.running_servers`.
:func:`redis_counters` reads the Redis ``INFO`` counters the report divides by
the frames tracked.
"""

from __future__ import annotations

import contextlib
import shutil
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import redis

from bench.common.processes import HOST, free_port, stop


@dataclass(frozen=True, slots=True)
class RedisProcess:
    """A running ``redis-server``: its process id and ``redis://`` URL."""

    pid: int
    url: str


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
        stop(process)


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


def redis_version() -> str:
    """``redis-server X.Y.Z`` (``redis-server ?`` when it does not say)."""
    try:
        text = subprocess.run(
            ["redis-server", "--version"], capture_output=True, text=True, timeout=10, check=True
        ).stdout
    except (OSError, subprocess.SubprocessError):
        return "redis-server ?"
    for part in text.split():
        if part.startswith("v="):
            return f"redis-server {part[2:]}"
    return "redis-server ?"
