"""Starting a track from a box: how close the snapped contour gets, how fast, and what it costs.

``python -m bench.tracking.snap [--quick] [--out DIR]`` takes each DAVIS-2016 sequence there is
(the thirty training and the five validation ones), the box of its first mask (pixel edges),
and writes ``snap.md`` and ``snap.json``:

- the IoU with the first mask of the box snapped onto the object
  (:func:`engine.tracking.snap.snap` with the second frame, as ``efdm track --init-box``
  does) and of its contours drawn from it (128 nodes for the largest piece), and the IoU
  of the snap from the first frame alone (colour only);
- the time of one snap (one thread; 854 x 480 frames);
- the mean J over the sequence (DAVIS protocol, 128 nodes) of the tracker started from the
  snapped box against the tracker started from the mask, each from every piece of at least
  :data:`engine.geometry.MIN_PIECE_AREA` pixels, as ``efdm track`` starts.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common.data import davis_names
from bench.common.study import on_two_processes, study_main

NODES = 128
"""Contour nodes, as the tracking benchmark's."""
QUICK_SEQUENCES = 2
"""Sequences per set with ``--quick``."""


def _sequence(job: tuple[str, str, str]) -> dict[str, Any]:
    """Snap and track one sequence both ways."""
    label, name, root = job
    import cv2

    cv2.setNumThreads(1)
    from bench.common.data import load_davis
    from bench.tracking.run import filled, initial_contours
    from bench.tracking.trackers import efdm_factory
    from engine.geometry import MIN_PIECE_AREA, mask_iou, mask_to_contours
    from engine.tracking.snap import snap

    clip = load_davis(name, root=Path(root))
    first = clip.masks[0]
    ys, xs = np.nonzero(first)
    box = (int(xs.min()), int(ys.min()), int(xs.max()) + 1, int(ys.max()) + 1)
    start = time.perf_counter()
    snapped = snap(clip.frames[0], box, next_frame=clip.frames[1])
    seconds = time.perf_counter() - start
    alone = snap(clip.frames[0], box)
    # both as efdm track starts: every piece of the mask, every piece of the snap
    box_start = mask_to_contours(snapped, NODES, min_area=MIN_PIECE_AREA)
    starts = {"mask": initial_contours(clip, NODES), "box": box_start}
    make = efdm_factory()
    scores = {}
    for way, contours in starts.items():
        tracker = make(contours)
        j = []
        for frame, mask in zip(clip.frames, clip.masks, strict=True):
            j.append(mask_iou(filled(tracker.step(frame).contours, mask.shape), mask))
        scores[way] = float(np.mean(j[1:-1]))
    return {
        "set": label,
        "name": name,
        "snap_iou": mask_iou(snapped, first),
        "colour_iou": mask_iou(alone, first),
        "contour_iou": mask_iou(filled(box_start, first.shape), first),
        "seconds": seconds,
        "j_mask": scores["mask"],
        "j_box": scores["box"],
    }


def run(sets: dict[str, Path], quick: bool) -> dict[str, Any]:
    """Every sequence of every set, on two processes."""
    jobs = [
        (label, name, str(root))
        for label, root in sets.items()
        for name in davis_names(root)[: QUICK_SEQUENCES if quick else None]
    ]
    done = on_two_processes(_sequence, jobs)
    out: dict[str, Any] = {}
    for label in sets:
        mine = [d for d in done if d["set"] == label]
        out[label] = {
            "sequences": len(mine),
            "snap_iou": float(np.mean([d["snap_iou"] for d in mine])),
            "colour_iou": float(np.mean([d["colour_iou"] for d in mine])),
            "contour_iou": float(np.mean([d["contour_iou"] for d in mine])),
            "seconds_median": float(np.median([d["seconds"] for d in mine])),
            "seconds_max": float(max(d["seconds"] for d in mine)),
            "j_mask": float(np.mean([d["j_mask"] for d in mine])),
            "j_box": float(np.mean([d["j_box"] for d in mine])),
            "per_sequence": {d["name"]: {k: v for k, v in d.items() if k != "name"} for d in mine},
        }
    return out


def render(results: dict[str, Any], seconds: float) -> str:
    """The markdown report."""
    lines = [
        "# Snap: a track started from a box",
        "",
        f"- date: {time.strftime('%Y-%m-%dT%H:%M:%S%z')}; {seconds:.0f} s wall time;"
        " `python -m bench.tracking.snap`",
        f"- the box of each sequence's first mask; {NODES} nodes; J over frames 1..T-2,"
        " mean of the per-sequence means; snap times on one thread, two processes running",
        "",
        "| set | sequences | first frame: snapped mask IoU | its contours' IoU (goal >= 0.75) "
        "| from the first frame alone | snap s (median, max; goal < 1) | J from the mask "
        "| J from the box (goal: within 0.08) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, r in results.items():
        lines.append(
            f"| {label} | {r['sequences']} | {r['snap_iou']:.3f} | {r['contour_iou']:.3f} "
            f"| {r['colour_iou']:.3f} | {r['seconds_median']:.2f}, {r['seconds_max']:.2f} "
            f"| {r['j_mask']:.3f} "
            f"| {r['j_box']:.3f} ({r['j_box'] - r['j_mask']:+.3f}) |"
        )
    lines += [
        "",
        "Per sequence (first-frame IoU of the snapped mask, J from the mask, from the box):",
        "",
    ]
    for label, r in results.items():
        worst = sorted(r["per_sequence"].items(), key=lambda kv: kv[1]["snap_iou"])
        cells = [
            f"{n} {d['snap_iou']:.2f} ({d['j_mask']:.2f} / {d['j_box']:.2f})" for n, d in worst
        ]
        lines.append(f"- {label}: " + ", ".join(cells))
    lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    return study_main(argv, __doc__, "snap", run, render, f"{QUICK_SEQUENCES} sequences a set")


if __name__ == "__main__":
    sys.exit(main())
