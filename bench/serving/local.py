"""The in-process baselines: ``engine.Tracker`` and ``engine.deform`` without the service.

The tracker baseline decodes every JPEG with ``cv2.imdecode`` (as the service
must) and steps the tracker, on this process's main thread.
"""

from __future__ import annotations

import time

import cv2
import numpy as np

from bench.serving.data import JpegClip
from bench.serving.stats import FrameRun, Measurement, metered
from engine import Tracker, deform

LOCAL = "in-process (imdecode + Tracker.step)"


def run_local(clip: JpegClip, seconds: float) -> FrameRun:
    """Track ``clip`` in-process until done or ``seconds`` have passed.

    Returns
    -------
    FrameRun
        ``latencies_ms``: decode + step per frame; ``server_ms``: the step alone.
    """
    row = Measurement(LOCAL, "frames")
    run = FrameRun(row)
    tracker = Tracker(clip.nodes)
    deadline = time.monotonic() + seconds
    with metered(row, ()):
        start = time.perf_counter()
        for data in clip.frames:
            if time.monotonic() > deadline:
                break
            t0 = time.perf_counter()
            frame = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
            t1 = time.perf_counter()
            result = tracker.step(np.asarray(frame, dtype=np.uint8))
            t2 = time.perf_counter()
            row.latencies_ms.append((t2 - t0) * 1e3)
            row.server_ms.append((t2 - t1) * 1e3)
            run.nodes.append(np.array(result.nodes, dtype=np.float64))
            row.sent += 1
            row.items += 1
        row.seconds = time.perf_counter() - start
    return run


def forces_payload(count: int) -> bytes:
    """The JSON body of a ``/forces`` request: ``count`` smooth forces, [fx, fy] each."""
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    forces = np.stack([3.0 * np.cos(3 * angle), -2.0 * np.sin(2 * angle)], axis=1)
    text = ",".join(f"[{fx:.6f},{fy:.6f}]" for fx, fy in forces)
    return f'{{"forces":[{text}]}}'.encode()


def local_deform_ms(count: int, repeats: int) -> float:
    """Median milliseconds of ``engine.deform`` ("exact", closed) on ``count`` nodes."""
    angle = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    forces = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    deform(forces, 10.0)
    samples = []
    for _ in range(max(1, repeats)):
        start = time.perf_counter()
        deform(forces, 10.0)
        samples.append((time.perf_counter() - start) * 1e3)
    return float(np.median(samples))
