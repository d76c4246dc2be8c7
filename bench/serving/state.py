"""What Redis stores per committed frame, and what resuming from it costs in tracking quality.

``python -m bench.serving.state [--quick] [--out DIR]`` tracks every DAVIS-2016 sequence
there is (the thirty training and the five validation ones; 128 nodes, DAVIS protocol) three
ways and writes ``state.md`` and ``state.json``:

- *uninterrupted*: one tracker throughout (the in-memory store, or a Redis replica going on
  from its exact copy of the session, :data:`service.redis_store.EXACT_CACHE`);
- *one failover*: at the middle frame the tracker is rebuilt from its compact state
  (:meth:`engine.Tracker.to_state` with ``compact=True``), as a replica taking over a
  stream after its first one died;
- *every frame elsewhere*: rebuilt from the compact state before every frame, the worst
  case (each request on another replica than the one before).

It also measures the JSON size of the exact and of the compact state after every frame:
the bytes each committed frame adds to Redis (and to its append-only file).
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common.data import davis_names
from bench.common.study import on_two_processes, study_main

NODES = 128
"""Contour nodes, as the tracking benchmark's."""
MODES = ("uninterrupted", "one failover", "every frame elsewhere")
QUICK_SEQUENCES = 2
"""Sequences per set with ``--quick``."""


def _track(job: tuple[str, str, str, str]) -> dict[str, Any]:
    """J per scored frame and state sizes for one sequence tracked one way."""
    label, name, root, mode = job
    import cv2

    cv2.setNumThreads(1)
    from bench.common.data import load_davis
    from engine.geometry import contour_to_mask, mask_iou, mask_to_contour
    from engine.tracking import Tracker

    clip = load_davis(name, root=Path(root))
    tracker = Tracker(mask_to_contour(clip.masks[0], NODES))
    scores, exact, compact = [], [], []
    middle = len(clip.frames) // 2
    for i, (frame, mask) in enumerate(zip(clip.frames, clip.masks, strict=True)):
        if i and (mode == MODES[2] or (mode == MODES[1] and i == middle)):
            tracker = Tracker.from_state(json.loads(json.dumps(tracker.to_state(compact=True))))
        result = tracker.step(frame)
        scores.append(mask_iou(contour_to_mask(result.nodes, mask.shape), mask))
        if mode == MODES[0]:  # as the service's record: the session's contour and rest too
            session = 2 * len(json.dumps(result.nodes.tolist()))
            exact.append(session + len(json.dumps(tracker.to_state())))
            compact.append(session + len(json.dumps(tracker.to_state(compact=True))))
    scored = scores[1:-1]
    j = float(np.mean(scored))
    return {"set": label, "name": name, "mode": mode, "j": j, "exact": exact, "compact": compact}


def run(sets: dict[str, Path], quick: bool) -> dict[str, Any]:
    """Every sequence of every set, every way, on two processes."""
    jobs = []
    for label, root in sets.items():
        names = davis_names(root)[: QUICK_SEQUENCES if quick else None]
        jobs += [(label, name, str(root), mode) for name in names for mode in MODES]
    done = on_two_processes(_track, jobs)
    out: dict[str, Any] = {}
    for label in sets:
        mine = [d for d in done if d["set"] == label]
        names = sorted({d["name"] for d in mine})
        by = {(d["name"], d["mode"]): d for d in mine}
        sizes = [by[n, MODES[0]] for n in names]
        exact = [s for d in sizes for s in d["exact"]]
        compact = [s for d in sizes for s in d["compact"]]
        base = {n: by[n, MODES[0]]["j"] for n in names}
        out[label] = {
            "sequences": len(names),
            "exact_bytes": {"mean": float(np.mean(exact)), "max": int(max(exact))},
            "compact_bytes": {"mean": float(np.mean(compact)), "max": int(max(compact))},
            "j": {m: float(np.mean([by[n, m]["j"] for n in names])) for m in MODES},
            "mean_abs_change": {
                m: float(np.mean([abs(by[n, m]["j"] - base[n]) for n in names])) for m in MODES
            },
            "per_sequence": {n: {m: by[n, m]["j"] for m in MODES} for n in names},
        }
    return out


def render(results: dict[str, Any], seconds: float) -> str:
    """The markdown report."""
    kb = 1024.0
    lines = [
        "# Session state in Redis: bytes per committed frame, and resuming from them",
        "",
        f"- date: {time.strftime('%Y-%m-%dT%H:%M:%S%z')}; {seconds:.0f} s wall time",
        f"- {NODES} nodes, DAVIS protocol (first and last frame left out, mean of per-sequence"
        " means); `python -m bench.serving.state`",
        "",
        "| set | sequences | exact record kB/frame (mean, max) | compact (mean, max) "
        "| J uninterrupted | J one failover | J every frame elsewhere |",
        "|---|---|---|---|---|---|---|",
    ]
    for label, r in results.items():
        e, c, j, d = r["exact_bytes"], r["compact_bytes"], r["j"], r["mean_abs_change"]
        lines.append(
            f"| {label} | {r['sequences']} | {e['mean'] / kb:.0f}, {e['max'] / kb:.0f} "
            f"| {c['mean'] / kb:.0f}, {c['max'] / kb:.0f} | {j[MODES[0]]:.3f} "
            f"| {j[MODES[1]]:.3f} (mean abs. change {d[MODES[1]]:.3f}) "
            f"| {j[MODES[2]]:.3f} (mean abs. change {d[MODES[2]]:.3f}) |"
        )
    lines += [
        "",
        "Redis holds the compact state (`Tracker.to_state(compact=True)`): the previous frame",
        "at half resolution around the contour and a quarter elsewhere (JPEG), p(object) around",
        "the contour as three levels, the colour histograms to three digits (float16); the",
        "search memory's shapes to a hundredth of a pixel and its hold factors and marks to",
        "three digits; contour and options exact.",
        "A replica that committed the version Redis holds goes on from its exact copy",
        "(`EFDM_REDIS_EXACT_CACHE` sessions), so a client served by one replica tracks as",
        "*uninterrupted*; *one failover* is a stream taken over by another replica mid-sequence;",
        "*every frame elsewhere* is the worst case, each request on another replica. Tracking is",
        "chaotic: one changed frame can move a sequence's J either way, hence the mean absolute",
        "change beside the mean.",
        "",
    ]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    return study_main(argv, __doc__, "state", run, render, f"{QUICK_SEQUENCES} sequences a set")


if __name__ == "__main__":
    sys.exit(main())
