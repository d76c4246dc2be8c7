"""Load benchmark results: the configuration, the rows, the markdown report and the JSON."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from bench.common.output import finite, run_json
from bench.common.report import fmt, header, load_line, plural
from bench.load.config import Config
from bench.serving.stats import Measurement


@dataclass(slots=True)
class LoadRow:
    """One row: a deployment (store and replicas) under one number of sessions.

    Attributes
    ----------
    store : str
        ``"in-memory"`` or ``"Redis"``.
    replicas : int
        ``efdm serve`` processes the sessions were spread over.
    measurement : Measurement
        Frames, latencies, dropped frames, errors; ``server_cpu`` summed over replicas.
    redis_commands, redis_round_trips, redis_cpu : float
        Differences of the Redis counters over the timed part (NaN without Redis).
    redis_calls : dict of str to int
        Calls per Redis command over the timed part.
    """

    store: str
    replicas: int
    measurement: Measurement
    redis_commands: float = math.nan
    redis_round_trips: float = math.nan
    redis_cpu: float = math.nan
    redis_calls: dict[str, int] = field(default_factory=dict)

    def add(self, other: LoadRow) -> None:
        """Pool another round of the same row into this one."""
        self.measurement.add(other.measurement)
        self.redis_commands += other.redis_commands
        self.redis_round_trips += other.redis_round_trips
        self.redis_cpu += other.redis_cpu
        for name, calls in other.redis_calls.items():
            self.redis_calls[name] = self.redis_calls.get(name, 0) + calls

    def per_frame(self, total: float) -> float:
        """A total over the timed part, per tracked frame."""
        items = self.measurement.items
        return total / items if items else math.nan


@dataclass(slots=True)
class Results:
    """Everything one run measured."""

    config: Config
    machine: dict[str, str]
    rows: list[LoadRow]
    notes: list[str] = field(default_factory=list)
    wall_seconds: float = 0.0


def _line(row: LoadRow) -> str:
    m = row.measurement
    cells = [
        row.store,
        str(row.replicas),
        str(m.clients),
        f"{m.items}/{m.sent}",
        fmt(m.rate, ".1f"),
        fmt(m.p(50), ".1f"),
        fmt(m.p(99), ".1f"),
        str(m.dropped),
        str(m.errors),
        fmt(row.per_frame(row.redis_round_trips), ".2f"),
        fmt(row.per_frame(row.redis_commands), ".2f"),
        fmt(m.per_item_ms(m.server_cpu), ".2f"),
        fmt(1e3 * row.per_frame(row.redis_cpu), ".2f"),
        fmt(m.per_item_ms(m.client_cpu), ".2f"),
    ]
    return "| " + " | ".join(cells) + " |"


def render(results: Results) -> str:
    """The markdown report."""
    m, c = results.machine, results.config
    lines = [
        *header(
            "Load benchmark: concurrent WebSocket sessions, 1 and 2 replicas",
            m,
            f"**{m['cpu_count']} CPUs shared by everything**: the replicas, redis-server and the "
            "benchmark's client (all traffic on 127.0.0.1), so adding a replica adds no cores",
            load_line(m),
        ),
        f"- python {m['python']}, uvicorn {m['uvicorn']}, fastapi {m['fastapi']}, websockets "
        f"{m['websockets']}, redis-py {m['redis']}, {m['redis_server']}",
        f"- run: `{c.name}`, {results.wall_seconds:.0f} s wall; rows of "
        f"{', '.join(map(str, c.sessions))} sessions, {plural(c.rounds, 'round')} pooled, "
        f"each row and round at most {c.row_seconds:g} s and max({c.frames_per_row} / "
        f"sessions, {c.min_frames_per_session}) frames per session",
        "",
        "## Results",
        "",
        "| store | replicas | sessions | frames done/sent | frames/s | p50 ms | p99 ms "
        "| dropped | errors | Redis round trips/frame | Redis commands/frame "
        "| replicas CPU ms/frame | Redis CPU ms/frame | client CPU ms/frame |",
        "|" + "---|" * 14,
        *(_line(row) for row in results.rows),
        "",
        "frames/s: frames tracked over the wall time of the timed part (all sessions "
        "together); latency: from sending a frame to receiving its result. Redis round "
        "trips: replies Redis wrote (`total_writes_processed`); commands: "
        "`total_commands_processed`, which also counts the commands Lua scripts run "
        "(per command in load.json); both over the timed part, per tracked frame. CPU: "
        "CPU seconds of the replica processes (together), of redis-server and of the "
        "benchmark's client process during the timed part, per frame.",
        "",
        "## Notes",
        "",
        *(f"- {note}" for note in results.notes),
    ]
    return "\n".join(lines) + "\n"


def row_json(row: LoadRow) -> dict[str, Any]:
    """One row's summary and raw latencies."""
    m = row.measurement
    return {
        "store": row.store,
        "replicas": row.replicas,
        "sessions": m.clients,
        "frames": m.items,
        "sent": m.sent,
        "seconds": m.seconds,
        "frames_per_second": finite(m.rate),
        "p50_ms": finite(m.p(50)),
        "p99_ms": finite(m.p(99)),
        "dropped": m.dropped,
        "errors": m.errors,
        "redis_round_trips_per_frame": finite(row.per_frame(row.redis_round_trips)),
        "redis_commands_per_frame": finite(row.per_frame(row.redis_commands)),
        "redis_calls_per_frame": {
            name: round(calls / m.items, 4) for name, calls in row.redis_calls.items() if m.items
        },
        "replicas_cpu_seconds": finite(m.server_cpu),
        "redis_cpu_seconds": finite(row.redis_cpu),
        "client_cpu_seconds": finite(m.client_cpu),
        "latencies_ms": [round(v, 3) for v in m.latencies_ms],
    }


def to_json(results: Results) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        **run_json(results),
        "rows": [row_json(r) for r in results.rows],
        "notes": results.notes,
        "units": {"latencies_ms": "send to result", "cpu": "seconds over the timed part"},
    }


def sessions_label(count: int) -> str:
    """``1 session``, ``10 sessions``."""
    return plural(count, "session")
