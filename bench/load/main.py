"""Load benchmark: many concurrent WebSocket sessions on 1 and 2 replicas sharing one Redis.

Rows, each with 1, 10 and 100 concurrent sessions (``--quick``: 1 and 4),
every session streaming small JPEG frames closed loop (the next frame when
the previous result arrived; 320 x 240 ``engine.synthetic`` frames):

- one ``efdm serve`` replica with the in-memory store (the reference);
- one replica with ``EFDM_REDIS_URL``;
- two replicas sharing that Redis, sessions spread round robin.

For each row: frames/s, latency p50/p99, dropped frames, errors, Redis round
trips and commands per frame (from Redis ``INFO`` before and after), and
the CPU time of the replicas, of Redis and of this client per frame.
redis-server and the replicas run as subprocesses on free 127.0.0.1 ports
and are always stopped at the end (SIGTERM: the replicas shut down
gracefully; their exit codes are noted).  Every row is bounded in frames and
in time.  Run ``python bench/load.py`` (``make bench-load``); ``--quick``
for a smoke test, ``--out DIR`` for where ``load.md`` and ``load.json`` go
(default ``bench/results/``).  Progress goes to stderr.
"""

from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import redis

from _load_clients import Clip, Load, run_sessions, synthetic_clip
from _load_cluster import (
    RedisCounters,
    counters_overhead,
    difference,
    redis_counters,
    running_redis,
    running_replicas,
)
from _load_report import (
    FULL,
    QUICK,
    Config,
    LoadRow,
    Results,
    render,
    sessions_label,
    to_json,
)
from _machine import load_average, machine_info
from _output import quick_and_out, write_results
from _service_server import Server, cpu_seconds
from _service_stats import Measurement

REPO = Path(__file__).resolve().parent.parent
DEFAULT_OUT = REPO / "bench" / "results"


def log(message: str) -> None:
    """Progress line on stderr."""
    print(f"[bench/load] {message}", file=sys.stderr, flush=True)


@dataclass(slots=True)
class Meter:
    """Counters read right before and after a row's timed part.

    Redis is read on one open connection; what the readings themselves add
    (the first ``INFO`` and its reply) is measured once and subtracted.
    """

    servers: Sequence[Server]
    redis: redis.Redis | None
    server_cpu: float = 0.0
    client_cpu: float = 0.0
    counters: RedisCounters | None = None

    def _server_cpu(self) -> float:
        return sum(cpu_seconds(s.pid) for s in self.servers)

    def start(self) -> None:
        """Snapshot the counters."""
        self.counters = redis_counters(self.redis) if self.redis is not None else None
        self.server_cpu = self._server_cpu()
        self.client_cpu = time.process_time()

    def stop(self) -> None:
        """Differences since :meth:`start`, kept for :meth:`fill`."""
        self.client_cpu = time.process_time() - self.client_cpu
        self.server_cpu = self._server_cpu() - self.server_cpu
        if self.redis is not None and self.counters is not None:
            self.counters = difference(redis_counters(self.redis), self.counters)

    def fill(self, row: LoadRow, overhead: RedisCounters | None) -> LoadRow:
        """Put the differences, less the readings' own ``overhead``, into ``row``."""
        row.measurement.server_cpu = self.server_cpu
        row.measurement.client_cpu = self.client_cpu
        if self.counters is not None and overhead is not None:
            own = difference(self.counters, overhead)
            row.redis_commands = float(own.commands)
            row.redis_round_trips = float(own.replies)
            row.redis_cpu = self.counters.cpu_seconds
            row.redis_calls = own.calls
        return row


@dataclass(frozen=True, slots=True)
class Deployment:
    """Replicas serving the sessions of a row, and the Redis they share (if any)."""

    store: str
    servers: Sequence[Server]
    redis: redis.Redis | None = None
    overhead: RedisCounters | None = None


def measure(deployment: Deployment, clip: Clip, load: Load) -> LoadRow:
    """One row: ``load`` on ``deployment``."""
    store, servers = deployment.store, deployment.servers
    log(
        f"{store}, {len(servers)} replica(s): {sessions_label(load.sessions)} x "
        f"<= {load.frames_per_session} frames, <= {load.seconds:g} s"
    )
    meter = Meter(servers, deployment.redis)
    measured: Measurement = run_sessions(servers, clip, load, meter.start, meter.stop)
    measured.name = f"{store}, {len(servers)} replica(s), {sessions_label(load.sessions)}"
    log(
        f"  {measured.items} frames, {measured.rate:.1f} frames/s, p50 "
        f"{measured.p(50):.1f} ms, p99 {measured.p(99):.1f} ms, errors {measured.errors}"
    )
    return meter.fill(LoadRow(store, len(servers), measured), deployment.overhead)


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
        "log level warning; one process each (`python -m engine.cli serve`)",
        "Redis counters include the replicas' housekeeping during the timed part (new pool "
        "connections' HELLO / CLIENT SETINFO, health-check PINGs, the minutely expiry sweep)",
        "replica start-up (spawn to /readyz) in s: " + ", ".join(f"{s:.1f}" for s in starts),
        f"replica exit codes after SIGTERM (graceful shutdown; 0 expected): {ended}",
    ]


def run(config: Config) -> Results:
    """Start the processes, measure every row, stop them."""
    start = time.perf_counter()
    load_before = load_average()
    clip = synthetic_clip(config.clip_length, config.nodes)
    log(f"{clip.name}: {len(clip.frames)} frames, {clip.mean_bytes / 1024:.1f} KiB/frame")
    with contextlib.ExitStack() as stack:
        memory = stack.enter_context(running_replicas(1, {}))
        shared = stack.enter_context(running_redis())
        pair = stack.enter_context(running_replicas(2, {"EFDM_REDIS_URL": shared.url}))
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
    return results


def write_outputs(results: Results, out: Path) -> str:
    """Write ``load.md`` and ``load.json`` into ``out``; return the report."""
    report = render(results)
    write_results(out, "load", report, to_json(results))
    return report


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark, print the report, write the result files."""
    args = quick_and_out(__doc__, DEFAULT_OUT, argv)
    results = run(QUICK if args.quick else FULL)
    print(write_outputs(results, args.out), end="")
    log(f"wrote {args.out / 'load.md'} and load.json ({results.wall_seconds:.0f} s)")
    failed = sum(r.measurement.errors for r in results.rows)
    if failed or any(not math.isfinite(r.measurement.rate) for r in results.rows):
        log(f"{failed} error(s) or an empty row: see the table")
    return 0


if __name__ == "__main__":
    sys.exit(main())
