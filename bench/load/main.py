"""Load benchmark: many concurrent WebSocket sessions on 1 and 2 replicas sharing one Redis.

Rows, each with 1, 10 and 100 concurrent sessions (``--quick``: 1 and 4),
every session streaming small JPEG frames closed loop through the project's
client (the next frame when the previous result arrived; 320 x 240
``engine.testing.synthetic`` frames):

- one ``efdm serve`` replica with the in-memory store (the reference);
- one replica with ``EFDM_REDIS_URL``;
- two replicas sharing that Redis, sessions spread round robin.

For each row: frames/s, latency p50/p99, dropped frames, errors, Redis round
trips and commands per frame (from Redis ``INFO`` before and after), and
the CPU time of the replicas, of Redis and of this client per frame.
redis-server and the replicas run as subprocesses on free 127.0.0.1 ports
and are always stopped at the end (SIGTERM: the replicas shut down
gracefully; their exit codes are noted).  Every row is bounded in frames and
in time.  Run ``python -m bench.load`` (``make bench-load``); ``--quick``
for a smoke test, ``--out DIR`` for where ``load.md`` and ``load.json`` go
(default ``bench/results/``).  Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import time
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass

import redis

from bench.common.benchmark import Benchmark
from bench.common.log import log
from bench.common.machine import load_average, machine_info
from bench.load.cluster import (
    RedisCounters,
    counters_overhead,
    difference,
    redis_counters,
    redis_version,
    running_redis,
)
from bench.load.config import FULL, QUICK, Config
from bench.load.report import LoadRow, Results, render, sessions_label, to_json
from bench.load.sessions import Clip, Load, run_sessions, synthetic_clip
from bench.serving.server import Server, running_servers
from bench.serving.stats import Measurement, metered, together


@dataclass(frozen=True, slots=True)
class Deployment:
    """Replicas serving the sessions of a row, and the Redis they share (if any)."""

    store: str
    servers: Sequence[Server]
    redis: redis.Redis | None = None
    overhead: RedisCounters | None = None


@contextlib.contextmanager
def redis_counted(row: LoadRow, deployment: Deployment) -> Iterator[None]:
    """Put the Redis counters over the block into ``row`` (nothing without Redis).

    Redis is read on one open connection; what the readings themselves add
    (the first ``INFO`` and its reply) is measured once and subtracted.
    """
    client, overhead = deployment.redis, deployment.overhead
    if client is None or overhead is None:
        yield
        return
    before = redis_counters(client)
    yield
    counters = difference(redis_counters(client), before)
    own = difference(counters, overhead)
    row.redis_commands = float(own.commands)
    row.redis_round_trips = float(own.replies)
    row.redis_cpu = counters.cpu_seconds
    row.redis_calls = own.calls


def measure(deployment: Deployment, clip: Clip, load: Load) -> LoadRow:
    """One row: ``load`` on ``deployment``."""
    store, servers = deployment.store, deployment.servers
    log(
        f"{store}, {len(servers)} replica(s): {sessions_label(load.sessions)} x "
        f"<= {load.frames_per_session} frames, <= {load.seconds:g} s"
    )
    name = f"{store}, {len(servers)} replica(s), {sessions_label(load.sessions)}"
    measured = Measurement(name, "frames", clients=load.sessions)
    row = LoadRow(store, len(servers), measured)

    def timed() -> AbstractContextManager[object]:
        pids = [s.pid for s in servers]
        return together(redis_counted(row, deployment), metered(measured, pids))

    run_sessions(servers, clip, load, measured, timed)
    log(
        f"  {measured.items} frames, {measured.rate:.1f} frames/s, p50 "
        f"{measured.p(50):.1f} ms, p99 {measured.p(99):.1f} ms, errors {measured.errors}"
    )
    return row


def interleaved(deployments: Sequence[Deployment], clip: Clip, config: Config) -> list[LoadRow]:
    """Every row, ``config.rounds`` times, the deployments taking turns; rounds pooled.

    For each number of sessions the deployments run one after another, starting
    with a different one each time, so that all see the same (shared) machine.
    """
    pooled: dict[tuple[int, int], LoadRow] = {}
    turn = 0
    for r in range(config.rounds):
        log(f"round {r + 1}/{config.rounds}")
        for sessions in config.sessions:
            first = turn % len(deployments)
            turn += 1
            for i in [*range(first, len(deployments)), *range(first)]:
                row = measure(deployments[i], clip, config.load(sessions))
                if (i, sessions) in pooled:
                    pooled[i, sessions].add(row)
                else:
                    pooled[i, sessions] = row
    return [pooled[i, s] for i in range(len(deployments)) for s in config.sessions]


def notes_for(
    clip: Clip, exits: dict[str, list[int | None]], starts: list[float], config: Config
) -> list[str]:
    """What the reader needs to read the table right."""
    commit = os.environ.get("EFDM_STREAM_COMMIT_EVERY", "unset (the service default)")
    workers = os.environ.get("EFDM_WORKERS", "0 (one per core)")
    ended = "; ".join(f"{name}: {codes}" for name, codes in exits.items())
    return [
        "2 cores shared by everything: the replicas, redis-server and the Python client "
        "(which takes CPU from the servers, see the client CPU column). A second replica "
        "adds event loops and tracking threads but no cores, so its rows show the cost of "
        "sharing sessions through Redis, not horizontal scaling",
        f"frames: {clip.name}, {len(clip.frames)} frames played forward then back "
        f"(JPEG, {clip.mean_bytes / 1024:.1f} KiB/frame); every session starts from the first "
        f"frame's contour, {len(clip.nodes)} nodes",
        "each session sends one untimed frame first; the timed part starts when every "
        "session has its first result and ends when the last session is done",
        f"{config.rounds} round(s), pooled; in each, for each number of sessions, the three "
        "deployments run one after another (the first one rotating). All processes stay up "
        "for the whole run: the in-memory replica idles during the Redis rows, the second "
        "Redis replica during the 1-replica rows",
        "sessions are created through replica (i + 1) mod R and streamed from replica "
        "i mod R: with 2 replicas every session is made on one and tracked on the other",
        f"replica settings: EFDM_WORKERS {workers}, EFDM_STREAM_COMMIT_EVERY {commit}, "
        "log level warning; one process each (`python -m efdm_cli serve`)",
        "Redis counters include the replicas' housekeeping during the timed part (new pool "
        "connections' HELLO / CLIENT SETINFO, health-check PINGs, the minutely expiry sweep)",
        "replica start-up (spawn to /readyz) in s: " + ", ".join(f"{s:.1f}" for s in starts),
        f"replica exit codes after SIGTERM (graceful shutdown; 0 expected): {ended}",
    ]


def run(config: Config, args: argparse.Namespace) -> Results:
    """Start the processes, measure every row, stop them."""
    start = time.perf_counter()
    load_before = load_average()
    clip = synthetic_clip(config.clip_length, config.nodes)
    log(f"{clip.name}: {len(clip.frames)} frames, {clip.mean_bytes / 1024:.1f} KiB/frame")
    with contextlib.ExitStack() as stack:
        memory = stack.enter_context(running_servers(1, {}, "/readyz"))
        shared = stack.enter_context(running_redis())
        redis_env = {"EFDM_REDIS_URL": shared.url}
        pair = stack.enter_context(running_servers(2, redis_env, "/readyz"))
        client = stack.enter_context(redis.Redis.from_url(shared.url, socket_timeout=10.0))
        starts = [s.start_seconds for s in [*memory.servers, *pair.servers]]
        log(f"up: 1 in-memory replica, redis-server at {shared.url}, 2 Redis replicas")
        overhead = counters_overhead(client)
        deployments = [
            Deployment("in-memory", memory.servers),
            Deployment("Redis", pair.servers[:1], client, overhead),
            Deployment("Redis", pair.servers, client, overhead),
        ]
        rows = interleaved(deployments, clip, config)
    exits = {"in-memory": memory.exit_codes, "Redis": pair.exit_codes}
    machine = machine_info(
        ("uvicorn", "fastapi", "websockets", "redis"),
        load_before=load_before,
        load_after=load_average(),
        redis_server=redis_version(),
    )
    results = Results(config, machine, rows, notes_for(clip, exits, starts, config))
    results.wall_seconds = time.perf_counter() - start
    failed = sum(r.measurement.errors for r in rows)
    if failed or any(not math.isfinite(r.measurement.rate) for r in rows):
        log(f"{failed} error(s) or an empty row: see the table")
    return results


BENCHMARK = Benchmark("load", __doc__, FULL, QUICK, run, render, to_json)
