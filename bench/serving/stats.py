"""Service and load benchmark measurements: counts, latencies, CPU time, percentiles.

A :class:`Measurement` is one row of a report (a transport and a number of
clients); rounds of the same row are pooled with :meth:`Measurement.add`.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Iterator, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field

import httpx
import numpy as np
from numpy.typing import NDArray

from bench.common.processes import cpu_seconds
from bench.serving.server import frame_seconds

Nodes = NDArray[np.float64]


def percentile(values: Sequence[float], q: float) -> float:
    """The ``q``-th percentile (linear interpolation; NaN when empty)."""
    return float(np.percentile(values, q)) if len(values) else math.nan


def median(values: Sequence[float]) -> float:
    """The median (NaN when empty)."""
    return percentile(values, 50.0)


@dataclass(slots=True)
class Measurement:
    """What one row of the report measured.

    Attributes
    ----------
    name : str
        Row label (transport and mode).
    kind : str
        ``"frames"`` or ``"requests"`` (the unit of :attr:`items`).
    clients : int
        Concurrent sessions / clients.
    items : int
        Frames tracked or requests answered.
    seconds : float
        Wall time the items took (summed over pooled rounds).
    latencies_ms : list of float
        Per item: from sending to receiving its result.
    server_ms : list of float
        Per frame: ``elapsed_ms`` the server reported (tracker step + result).
    dropped, errors : int
        Frames the server skipped (open loop); non-success answers.
    sent : int
        Frames or requests sent.
    server_cpu, client_cpu : float
        CPU seconds of the server process(es, together) and of this process during the row.
    handler_seconds, handler_count : float, int
        The server's own timing of the frames (``efdm_frame_seconds`` from
        ``/metrics``: lease, decode, worker thread, step), summed.
    reported_ms : dict of int to float
        Latency percentiles a load generator reported itself (when
        ``latencies_ms`` is empty), by percentile.
    note : str
        How it was measured, or why it was not.
    """

    name: str
    kind: str
    clients: int = 1
    items: int = 0
    seconds: float = 0.0
    latencies_ms: list[float] = field(default_factory=list)
    server_ms: list[float] = field(default_factory=list)
    dropped: int = 0
    errors: int = 0
    sent: int = 0
    server_cpu: float = 0.0
    client_cpu: float = 0.0
    handler_seconds: float = 0.0
    handler_count: int = 0
    reported_ms: dict[int, float] = field(default_factory=dict)
    note: str = ""

    @property
    def rate(self) -> float:
        """Items per second (NaN when nothing ran)."""
        return self.items / self.seconds if self.seconds > 0 and self.items else math.nan

    def p(self, q: float) -> float:
        """Latency percentile, milliseconds (NaN when not measured)."""
        if not self.latencies_ms:
            return self.reported_ms.get(round(q), math.nan)
        return percentile(self.latencies_ms, q)

    @property
    def handler_ms(self) -> float:
        """Mean server-side frame time, ms (NaN when not read)."""
        return 1e3 * self.handler_seconds / self.handler_count if self.handler_count else math.nan

    @property
    def mean_ms(self) -> float:
        """Mean latency, ms (NaN when empty)."""
        return float(np.mean(self.latencies_ms)) if self.latencies_ms else math.nan

    def per_item_ms(self, cpu_seconds_total: float) -> float:
        """CPU milliseconds per item."""
        return 1e3 * cpu_seconds_total / self.items if self.items else math.nan

    def add(self, other: Measurement) -> None:
        """Pool another round of the same row into this one."""
        self.items += other.items
        self.seconds += other.seconds
        self.latencies_ms += other.latencies_ms
        self.server_ms += other.server_ms
        self.dropped += other.dropped
        self.errors += other.errors
        self.sent += other.sent
        self.server_cpu += other.server_cpu
        self.client_cpu += other.client_cpu
        self.handler_seconds += other.handler_seconds
        self.handler_count += other.handler_count
        self.note = self.note or other.note


@dataclass(slots=True)
class FrameRun:
    """A row's measurement on one clip, with the contour of every tracked frame."""

    measurement: Measurement
    nodes: list[Nodes] = field(default_factory=list)


@contextlib.contextmanager
def metered(row: Measurement, server_pids: Sequence[int]) -> Iterator[None]:
    """Add the servers' (together) and this process's CPU seconds during the block to ``row``.

    Without servers (``server_pids`` empty) the row's server CPU becomes NaN.
    """

    def servers() -> float:
        return sum(cpu_seconds(pid) for pid in server_pids)

    server_before = servers()
    client_before = time.process_time()
    try:
        yield
    finally:
        row.client_cpu += time.process_time() - client_before
        if server_pids:
            row.server_cpu += servers() - server_before
        else:
            row.server_cpu = math.nan


@contextlib.contextmanager
def handler_timed(row: Measurement, url: str, transport: str) -> Iterator[None]:
    """Add the server's own frame timings during the block (from ``/metrics``) to ``row``."""
    with httpx.Client(base_url=url, timeout=10.0) as client:
        sum_before, count_before = frame_seconds(client, transport)
        yield
        sum_after, count_after = frame_seconds(client, transport)
    row.handler_seconds += sum_after - sum_before
    row.handler_count += count_after - count_before


@contextlib.contextmanager
def together(*managers: AbstractContextManager[object]) -> Iterator[None]:
    """Enter ``managers`` in order for the block (and leave them in reverse)."""
    with contextlib.ExitStack() as stack:
        for manager in managers:
            stack.enter_context(manager)
        yield


def max_difference(a: Sequence[Nodes], b: Sequence[Nodes]) -> float:
    """Largest coordinate difference between two runs' contours (inf if they differ in length)."""
    if len(a) != len(b):
        return math.inf
    worst = 0.0
    for x, y in zip(a, b, strict=True):
        xa, ya = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        if xa.shape != ya.shape:
            return math.inf
        worst = max(worst, float(np.max(np.abs(xa - ya))) if xa.size else 0.0)
    return worst


def paired_overhead(service: Measurement, local: Measurement) -> float:
    """Median of per-frame (service latency - in-process decode + step), ms (NaN if unpaired)."""
    if not local.latencies_ms or len(service.latencies_ms) != len(local.latencies_ms):
        return math.nan
    diffs = np.subtract(service.latencies_ms, local.latencies_ms)
    return float(np.median(diffs))
