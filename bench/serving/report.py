"""Service benchmark results: goals, the markdown report and the raw JSON."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from bench.common.output import finite, run_json
from bench.common.report import GoalLine, fmt, goals_json, goals_table, header, load_line, plural
from bench.serving.config import Config
from bench.serving.stats import Measurement, median, paired_overhead

WS_RATIO_GOAL = 0.70
FORCES_GOAL = 1000.0


@dataclass(slots=True)
class Results:
    """Everything one run measured.

    ``local``, ``ws``, ``ws_plain`` and ``rest`` are the single-session rows the
    breakdown and the goals use; ``rows`` holds every row in report order.
    """

    config: Config
    machine: dict[str, str]
    rows: list[Measurement]
    local: Measurement
    ws: Measurement
    ws_plain: Measurement
    rest: Measurement
    deform_ms: float
    consistency: dict[str, float] = field(default_factory=dict)
    cold_ms: list[float] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    wall_seconds: float = 0.0


def ratio(row: Measurement, local: Measurement) -> float:
    """A frames row's rate over the in-process rate (NaN for requests rows)."""
    if row.kind != "frames" or not math.isfinite(local.rate):
        return math.nan
    return row.rate / local.rate


def best_forces(results: Results) -> Measurement | None:
    """The ``/forces`` row with the highest requests/s."""
    rows = [r for r in results.rows if r.kind == "requests" and math.isfinite(r.rate)]
    return max(rows, key=lambda r: r.rate) if rows else None


def goals(results: Results) -> list[GoalLine]:
    """The benchmark's goals against what was measured."""
    share = ratio(results.ws, results.local)
    plain = ratio(results.ws_plain, results.local)
    best = best_forces(results)
    forces = best.rate if best is not None else math.nan
    where = f" ({best.name}, {plural(best.clients, 'client')})" if best is not None else ""
    return [
        GoalLine.at_least(
            "WebSocket closed loop fps / in-process fps (1 session)",
            share,
            f"{fmt(100 * share, '.0f')} % ({fmt(results.ws.rate, '.1f')} vs "
            f"{fmt(results.local.rate, '.1f')} fps; no compression offered: "
            f"{fmt(100 * plain, '.0f')} %)",
            WS_RATIO_GOAL,
            f">= {100 * WS_RATIO_GOAL:.0f} %",
        ),
        GoalLine.at_least(
            f"REST /forces requests/s ({results.config.forces_nodes} nodes, best client)",
            forces,
            f"{fmt(forces, '.0f')}{where}",
            FORCES_GOAL,
            f">= {FORCES_GOAL:,.0f} req/s",
        ),
    ]


def _row_line(row: Measurement, local: Measurement) -> str:
    unit = "fps" if row.kind == "frames" else "req/s"
    share = ratio(row, local)
    cells = [
        row.name,
        str(row.clients),
        f"{row.items}/{row.sent}",
        f"{fmt(row.rate, '.1f')} {unit}" if math.isfinite(row.rate) else "-",
        f"{fmt(100 * share, '.0f')} %" if math.isfinite(share) else "",
        fmt(row.p(50), ".2f"),
        fmt(row.p(95), ".2f"),
        fmt(row.p(99), ".2f"),
        str(row.dropped) if row.kind == "frames" else "",
        str(row.errors),
        fmt(row.per_item_ms(row.server_cpu), ".2f"),
        fmt(row.per_item_ms(row.client_cpu), ".2f"),
    ]
    return "| " + " | ".join(cells) + " |"


def results_table(results: Results) -> list[str]:
    """The main table: one line per measurement."""
    head = (
        "| measurement | sessions / clients | done / sent | rate | vs in-process | p50 ms "
        "| p95 ms | p99 ms | dropped | errors | server CPU ms/item | client CPU ms/item |"
    )
    lines = [head, "|" + "---|" * 12]
    lines += [_row_line(row, results.local) for row in results.rows]
    return lines


def breakdown(results: Results) -> dict[str, float]:
    """Medians of where one frame's time goes (single session, closed loop)."""
    local, ws, rest = results.local, results.ws, results.rest
    decode = [t - s for t, s in zip(local.latencies_ms, local.server_ms, strict=True)]
    return {
        "in-process JPEG decode": median(decode),
        "in-process Tracker.step": median(local.server_ms),
        "in-process decode + step": local.p(50),
        "server-reported elapsed_ms (step + result lists), WebSocket": median(ws.server_ms),
        "WebSocket round trip": ws.p(50),
        "mean WebSocket round trip": ws.mean_ms,
        "mean server handler time (lease, decode, worker thread, step), WebSocket": ws.handler_ms,
        "mean round trip - handler time (client, transport, event loop), WebSocket": (
            ws.mean_ms - ws.handler_ms
        ),
        "WebSocket round trip - in-process, paired per frame": paired_overhead(ws, local),
        "REST /frames round trip": rest.p(50),
        "REST round trip - in-process, paired per frame": paired_overhead(rest, local),
        "mean REST round trip - handler time (client, HTTP, middleware, event loop)": (
            rest.mean_ms - rest.handler_ms
        ),
        "CPU per frame, in-process": local.per_item_ms(local.client_cpu),
        "CPU per frame, WebSocket: server": ws.per_item_ms(ws.server_cpu),
        "CPU per frame, WebSocket: client": ws.per_item_ms(ws.client_cpu),
        "CPU per frame, REST: server": rest.per_item_ms(rest.server_cpu),
        "server CPU per frame beyond in-process decode + step, WebSocket": (
            ws.per_item_ms(ws.server_cpu) - local.per_item_ms(local.client_cpu)
        ),
    }


def render(results: Results) -> str:
    """The markdown report."""
    m, c = results.machine, results.config
    lines = header(
        "Service overhead benchmark",
        m,
        f"{m['cpu_count']} CPUs shared by the server and the benchmark's clients (all traffic "
        "on 127.0.0.1)",
        load_line(m),
        f"- python {m['python']}, numpy {m['numpy']}, opencv {m['opencv']} "
        f"({m['cv_threads']} OpenCV threads), uvicorn {m['uvicorn']}, fastapi {m['fastapi']}, "
        f"websockets {m['websockets']}, httpx {m['httpx']}, wrk {m['wrk']}",
        f"- run: `{c.name}`, {plural(c.rounds, 'interleaved round')}, "
        f"{results.wall_seconds:.0f} s wall; server `python -m efdm_cli serve` started "
        f"in {m['server_start']} s",
    )
    lines += ["", "## Goals", "", goals_table(goals(results))]
    lines += ["", "## Results", "", *results_table(results), ""]
    lines += [
        "Rates are items over wall time; latency is from sending a frame or request to "
        "receiving its answer (open loop: of the frames that were tracked). CPU columns: "
        "CPU seconds of the server process and of the benchmark process (the Python "
        "client; for wrk rows, wrk) during the row, per item.",
        "",
        "## Where a frame's time goes (1 session, closed loop; medians unless marked mean)",
        "",
        "| part | ms |",
        "|---|---|",
    ]
    lines += [f"| {k} | {fmt(v, '.2f')} |" for k, v in breakdown(results).items()]
    lines += ["", "## Notes", ""]
    lines += [f"- {note}" for note in results.notes]
    return "\n".join(lines) + "\n"


def row_json(row: Measurement) -> dict[str, Any]:
    """One row's summary and raw latencies."""
    return {
        "name": row.name,
        "kind": row.kind,
        "clients": row.clients,
        "items": row.items,
        "sent": row.sent,
        "seconds": row.seconds,
        "rate": finite(row.rate),
        "p50_ms": finite(row.p(50)),
        "p95_ms": finite(row.p(95)),
        "p99_ms": finite(row.p(99)),
        "dropped": row.dropped,
        "errors": row.errors,
        "server_cpu_seconds": finite(row.server_cpu),
        "client_cpu_seconds": finite(row.client_cpu),
        "note": row.note,
        "reported_ms": {str(k): v for k, v in row.reported_ms.items()},
        "latencies_ms": [round(v, 4) for v in row.latencies_ms],
        "server_elapsed_ms": [round(v, 4) for v in row.server_ms],
    }


def to_json(results: Results) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        **run_json(results),
        "goals": goals_json(goals(results)),
        "rows": [row_json(r) for r in results.rows],
        "breakdown_ms": {k: finite(v) for k, v in breakdown(results).items()},
        "max_node_difference_vs_in_process": {k: finite(v) for k, v in results.consistency.items()},
        "deform_ms_in_process": finite(results.deform_ms),
        "cold_start_ms": results.cold_ms,
        "notes": results.notes,
        "units": {"latencies_ms": "send to answer", "rate": "frames or requests per second"},
    }
