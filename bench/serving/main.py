"""Service overhead benchmark: a real ``efdm serve`` against ``engine.Tracker`` in-process.

One run measures side by side, on the same 480p JPEG frames (DAVIS-2016
blackswan and dog, initial contour from the first mask, 128 nodes; else
``engine.testing.synthetic`` sequences):

- in-process: ``cv2.imdecode`` + ``Tracker.step`` per frame (the service
  must decode too);
- one WebSocket session, closed loop (next frame when the previous result
  arrived), offering permessage-deflate (as the ``websockets`` library does
  by default) or not (as ``service.client`` does); and open loop (frames on a
  clock faster than tracking, so the server drops some);
- several concurrent WebSocket sessions, each closed loop;
- REST ``/frames`` for one session, closed loop;
- REST ``/forces`` (256 nodes) from 1 and 8 concurrent httpx clients, and from
  ``wrk`` when installed.

The service rows talk to the server through the project's client
(``service.client``; see :mod:`bench.serving.client` for the little it adds).
The server runs as a subprocess (``python -m efdm_cli serve``) on a free
127.0.0.1 port and is always terminated at the end.  Every loop is bounded
in count and time.  Run ``python -m bench.serving`` (``make bench-service``);
``--quick`` for a smoke test, ``--out DIR`` for where ``service.md`` and
``service.json`` go (default ``bench/results/``).  Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from collections.abc import Callable

import cv2

import engine
from bench.common import machine
from bench.common.benchmark import Benchmark
from bench.common.log import log
from bench.common.machine import load_average
from bench.common.report import plural
from bench.serving.config import FULL, QUICK, Config
from bench.serving.data import JpegClip, load_clips
from bench.serving.local import LOCAL, forces_payload, local_deform_ms, run_local
from bench.serving.report import Results, render, to_json
from bench.serving.rest import ForcesLoad, rest_forces, rest_frames
from bench.serving.server import Server, running_servers
from bench.serving.stats import FrameRun, Measurement, max_difference
from bench.serving.wrk import available as wrk_path
from bench.serving.wrk import wrk_forces
from bench.serving.ws import StreamSpec, ws_closed_loop, ws_concurrent, ws_open_loop

WS = "WebSocket, closed loop (deflate offered: websockets' default)"
WS_PLAIN = "WebSocket, closed loop (no compression offered)"
REST = "REST /frames, closed loop"
SINGLE = (LOCAL, WS, WS_PLAIN, REST)


def machine_info() -> dict[str, str]:
    """Platform, CPU, library versions and the date."""
    return machine.machine_info(
        ("uvicorn", "fastapi", "websockets", "httpx"),
        opencv=cv2.__version__,
        cv_threads=str(cv2.getNumThreads()),
        wrk="installed" if wrk_path() else "absent",
    )


def head(clip: JpegClip, count: int) -> JpegClip:
    """The first ``count`` frames of a clip."""
    return dataclasses.replace(clip, frames=clip.frames[:count])


def warm_up(server: Server, clips: list[JpegClip], config: Config) -> list[float]:
    """Untimed first frames everywhere; returns the server's cold-start latencies (ms)."""
    engine.warm_up()
    seconds = config.row_seconds
    cold = ws_closed_loop(server, head(clips[0], 3), StreamSpec("cold", "deflate", seconds))
    for clip in clips:
        run_local(head(clip, 4), seconds)
        ws_closed_loop(server, head(clip, 4), StreamSpec("warm", None, seconds))
        rest_frames(server, head(clip, 2), "warm", seconds)
    return cold.measurement.latencies_ms


def one_round(server: Server, clip: JpegClip, config: Config, turn: int) -> dict[str, FrameRun]:
    """The single-session rows on one clip, one after another, starting at row ``turn``."""
    seconds = config.row_seconds
    measure: dict[str, Callable[[], FrameRun]] = {
        LOCAL: lambda: run_local(clip, seconds),
        WS: lambda: ws_closed_loop(server, clip, StreamSpec(WS, "deflate", seconds)),
        WS_PLAIN: lambda: ws_closed_loop(server, clip, StreamSpec(WS_PLAIN, None, seconds)),
        REST: lambda: rest_frames(server, clip, REST, seconds),
    }
    order = [*SINGLE[turn % len(SINGLE) :], *SINGLE[: turn % len(SINGLE)]]
    return {name: measure[name]() for name in order}


def single_sessions(
    server: Server, clips: list[JpegClip], config: Config
) -> tuple[dict[str, Measurement], dict[str, float]]:
    """Interleaved rounds of the single-session rows; pooled rows and contour differences."""
    pooled = {name: Measurement(name, "frames") for name in SINGLE}
    worst = dict.fromkeys(SINGLE[1:], 0.0)
    for r in range(config.rounds):
        for i, clip in enumerate(clips):
            log(f"round {r + 1}/{config.rounds}: {clip.name} ({len(clip.frames)} frames)")
            runs = one_round(server, clip, config, r * len(clips) + i)
            for name, run in runs.items():
                pooled[name].add(run.measurement)
            for name in worst:
                worst[name] = max(worst[name], max_difference(runs[name].nodes, runs[LOCAL].nodes))
    return pooled, worst


def open_loop(server: Server, clips: list[JpegClip], rate: float, config: Config) -> Measurement:
    """Every clip streamed at ``rate`` frames/s, ``config.rounds`` times; pooled."""
    name = f"WebSocket, open loop at {rate:.0f} fps (deflate offered)"
    row = Measurement(name, "frames")
    for _ in range(config.rounds):
        for clip in clips:
            spec = StreamSpec(name, "deflate", config.row_seconds)
            row.add(ws_open_loop(server, clip, rate, spec))
    return row


def concurrent(server: Server, clips: list[JpegClip], config: Config) -> list[Measurement]:
    """Rows of several closed-loop sessions at once (``config.session_frames`` frames each)."""
    rows = []
    short = [head(clip, config.session_frames) for clip in clips]
    for sessions in config.sessions:
        log(f"{sessions} concurrent WebSocket sessions, {config.session_frames} frames each")
        name = f"WebSocket, {sessions} sessions, closed loop (deflate offered)"
        spec = StreamSpec(name, "deflate", config.row_seconds)
        rows.append(ws_concurrent(server, short, sessions, spec))
    return rows


def forces(server: Server, config: Config) -> list[Measurement]:
    """``/forces`` rows: httpx threads, then wrk (skipped with a note when absent)."""
    body = forces_payload(config.forces_nodes)
    rows = []
    for clients in config.forces_clients:
        log(f"/forces: {clients} httpx clients")
        each = max(1, config.forces_requests // clients)
        load = ForcesLoad(clients, each, config.forces_warmup, body, config.row_seconds)
        name = "REST /forces, httpx (1 thread per client)"
        rows.append(rest_forces(server, load, config.forces_nodes, name))
    for clients in config.forces_clients:
        log(f"/forces: wrk, {clients} connections, {config.wrk_seconds:g} s")
        load = ForcesLoad(clients, 0, 0, body, config.wrk_seconds)
        name = "REST /forces, wrk (1 thread)"
        rows.append(wrk_forces(server, load, config.forces_nodes, name))
    return rows


def notes_for(results: Results, clips: list[JpegClip], server_notes: list[str]) -> list[str]:
    """What the reader needs to read the tables right."""
    c = results.config
    sizes = ", ".join(
        f"{clip.name} {len(clip.frames)} frames {clip.shape[1]}x{clip.shape[0]}, "
        f"{clip.mean_bytes / 1024:.0f} KiB/frame"
        for clip in clips
    )
    worst = ", ".join(f"{k}: {v:.3g} px" for k, v in results.consistency.items())
    notes = [
        *server_notes,
        f"clips: {sizes}; the service rows track the same frames from the same contour",
        "the service rows use the project's client, service.client (bench/serving/client.py "
        "adds the compression offer and the open loop's raw socket)",
        f"single-session rows take turns clip by clip ({plural(c.rounds, 'round')}, the order "
        "rotating) so that they see the same machine state; timings are only as quiet as "
        "the machine (see the load averages)",
        "in-process: this process's main thread, default OpenCV / numba threading (as the "
        "server's); the server runs tracking in worker threads (at most one per core)",
        "2 cores serve both the server and the clients: Python clients take CPU from the "
        "server (client CPU column), so rates under concurrency are lower bounds",
        f"contours vs in-process, largest difference per row: {worst}",
        f"server cold start (first session, frames 0-2, ms): "
        f"{', '.join(f'{v:.1f}' for v in results.cold_ms)}",
        f"engine.deform in-process ({c.forces_nodes} nodes, exact): {results.deform_ms:.3f} ms",
    ]
    notes += [
        f"{row.name}, {plural(row.clients, 'client')}: {row.note}"
        for row in results.rows
        if row.note
    ]
    return notes


def run(config: Config, args: argparse.Namespace) -> Results:
    """Start the server, measure every row, stop the server."""
    start = time.perf_counter()
    load_before = load_average()
    clips, data_notes = load_clips(config.frames, config.synthetic_length)
    log(data_notes[0])
    deform_ms = local_deform_ms(config.forces_nodes, 200)
    with running_servers() as servers:
        server = servers.servers[0]
        log(f"efdm serve up at {server.url} in {server.start_seconds:.1f} s")
        cold = warm_up(server, clips, config)
        pooled, worst = single_sessions(server, clips, config)
        rates = [row.rate for row in pooled.values() if math.isfinite(row.rate)]
        fastest = max(rates, default=50.0)
        rate = config.open_rate_factor * fastest
        log(f"open loop at {rate:.0f} fps ({config.open_rate_factor:g} x the fastest row)")
        rows = [*pooled.values()]
        rows.insert(3, open_loop(server, clips, rate, config))
        rows[4:4] = concurrent(server, clips, config)
        rows += forces(server, config)
    machine = machine_info() | {
        "load_before": load_before,
        "load_after": load_average(),
        "server_start": f"{server.start_seconds:.1f}",
    }
    results = Results(
        config,
        machine,
        rows,
        pooled[LOCAL],
        pooled[WS],
        pooled[WS_PLAIN],
        pooled[REST],
        deform_ms,
        worst,
        cold,
    )
    results.notes = notes_for(results, clips, data_notes)
    results.wall_seconds = time.perf_counter() - start
    return results


BENCHMARK = Benchmark("serving", __doc__, FULL, QUICK, run, render, to_json, stem="service")
