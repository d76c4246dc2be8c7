"""Concurrent WebSocket sessions for the load benchmark, closed loop, one asyncio process.

Session ``i`` streams from replica ``i mod R`` (round robin) and is created
through replica ``i + 1 mod R``: with two replicas every session is made on
one and tracked on the other, through the shared store.  Each session sends
one untimed frame first; then all start together, each sending its next frame
when the previous result arrived, until its frame budget or the row's
deadline.  The sessions are the project's client streaming
(:func:`bench.serving.ws.closed_loops`); every wait has a timeout.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from bench.serving.client import BenchClient
from bench.serving.data import JpegClip, encode
from bench.serving.server import Server
from bench.serving.stats import Measurement
from bench.serving.ws import Plan, Timed, closed_loops
from engine.geometry import mask_to_contour
from engine.testing.synthetic import make_sequence

TIMEOUT = 30.0
"""Seconds for connecting and for each answer (100 sessions share two cores)."""

Clip = JpegClip
"""The frames every session streams (the service benchmark's clip type)."""


def synthetic_clip(length: int, nodes: int, size: tuple[int, int] = (240, 320)) -> Clip:
    """An ``engine.testing.synthetic`` "plain" sequence as JPEG, played forward then back.

    Forward-and-back keeps the motion continuous when a session loops over it.
    """
    sequence = make_sequence("plain", seed=0, length=length, size=size)
    jpeg = [encode(np.asarray(f, dtype=np.uint8)) for f in sequence.frames]
    order = [*jpeg, *jpeg[-2:0:-1]]
    contour = mask_to_contour(np.asarray(sequence.masks[0], dtype=np.uint8), nodes).tolist()
    name = f"synthetic plain {size[1]}x{size[0]}"
    return Clip(name, "engine.testing.synthetic", tuple(order), contour, size)


def cycle(clip: Clip, start: int) -> Iterator[bytes]:
    """The clip's frames from ``start`` on, looping forever."""
    i = start
    while True:
        yield clip.frames[i % len(clip.frames)]
        i += 1


@dataclass(frozen=True, slots=True)
class Load:
    """One row's load: sessions, frames per session and the time limit."""

    sessions: int
    frames_per_session: int
    seconds: float


async def _run(
    servers: Sequence[Server], clip: Clip, load: Load, row: Measurement, timed: Timed
) -> None:
    clients = [BenchClient(s.url, compression=None, timeout=TIMEOUT) for s in servers]
    try:
        ids = [
            (await clients[(i + 1) % len(clients)].create_session(clip.nodes)).id
            for i in range(load.sessions)
        ]
        plans = [
            Plan(
                clients[i % len(clients)],
                sid,
                itertools.islice(cycle(clip, 1), load.frames_per_session),
                warm=clip.frames[0],
            )
            for i, sid in enumerate(ids)
        ]
        await closed_loops(plans, load.seconds, row, timed)
    finally:
        await asyncio.gather(*(c.aclose() for c in clients))


def run_sessions(
    servers: Sequence[Server], clip: Clip, load: Load, row: Measurement, timed: Timed
) -> None:
    """Stream ``load.sessions`` closed-loop sessions round-robin over ``servers`` into ``row``.

    Parameters
    ----------
    servers : sequence of Server
        The replicas (sharing one store when more than one).
    clip : Clip
        Frames to stream; every session starts from the clip's first contour.
    load : Load
        Sessions, frame budget per session and time limit of the timed part.
    row : Measurement
        Gets the frames tracked, latencies, dropped frames and errors of the
        timed part; ``seconds`` is its wall time.  Sessions that failed to
        open or to warm up count as errors.
    timed : callable
        What to read around the timed part (CPU time, Redis counters).
    """
    asyncio.run(_run(servers, clip, load, row, timed))
