"""Tracking benchmark results: goals, the markdown report and the raw JSON."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bench.common.output import finite, run_json
from bench.common.report import (
    GoalLine,
    fmt,
    goals_json,
    goals_table,
    header,
    load_line,
    md_table,
    verdict,
)
from bench.tracking.config import NODES, Config
from bench.tracking.plots import DAVIS_GOAL, SYNTHETIC_GOAL
from bench.tracking.run import ClipResult, mean_j, pooled_median_ms
from bench.tracking.trackers import SKIMAGE_PARAMS, SKIMAGE_SIGMA

SPEEDUP_GOAL = 20.0
FPS_GOAL = 100.0
REFERENCE_SEQUENCES = ("blackswan", "car-shadow", "dog", "soapbox", "breakdance")
REFERENCES: dict[str, tuple[float, ...]] = {
    "static": (0.547, 0.402, 0.325, 0.133, 0.234, 0.328),
    "edge+EFDM": (0.586, 0.501, 0.440, 0.360, 0.259, 0.429),
    "rigid LK": (0.921, 0.777, 0.345, 0.520, 0.233, 0.559),
    "rigid+snap": (0.867, 0.845, 0.384, 0.567, 0.242, 0.581),
    "skimage": (0.087, 0.428, 0.083, 0.146, 0.057, 0.160),
}
"""Mean J of the DAVIS README's reference trackers: per sequence, then the mean."""


@dataclass(slots=True)
class Results:
    """Everything one run measured."""

    config: Config
    trackers: tuple[str, ...]
    davis: list[ClipResult]
    synthetic: list[ClipResult]
    machine: dict[str, str]
    wall_seconds: float
    notes: list[str] = field(default_factory=list)
    unavailable: dict[str, str] = field(default_factory=dict)
    sheets: list[str] = field(default_factory=list)


def reference(tracker: str, sequence: str) -> float:
    """The README's J of a reference tracker on a sequence (``"mean"``: over the five)."""
    names = (*REFERENCE_SEQUENCES, "mean")
    return REFERENCES[tracker][names.index(sequence)] if sequence in names else math.nan


def speed_clips(results: Results) -> tuple[list[ClipResult], str]:
    """The clips the speed goals are measured on: DAVIS 480p, else synthetic."""
    if results.davis:
        return results.davis, "DAVIS 480p"
    return results.synthetic, "synthetic 480x640"


def partial_davis(results: Results) -> bool:
    """Whether the DAVIS part is not the README's five full sequences."""
    names = {c.name for c in results.davis}
    return names != set(REFERENCE_SEQUENCES) or results.config.davis_frames is not None


def score_goal(label: str, value: float, target: float) -> GoalLine:
    """A ``mean J >= target`` goal."""
    return GoalLine.at_least(label, value, fmt(value, ".3f"), target, f">= {target:g}")


def goals(results: Results) -> list[GoalLine]:
    """Every goal line: DAVIS mean J, each synthetic condition, speed-up and frame rate."""
    lines: list[GoalLine] = []
    if results.davis:
        subset = " *" if partial_davis(results) else ""
        value = mean_j(results.davis, "efdm")
        lines.append(score_goal(f"DAVIS mean J (efdm){subset}", value, DAVIS_GOAL))
    for clip in results.synthetic:
        value = clip.runs["efdm"].mean_j if "efdm" in clip.runs else math.nan
        lines.append(score_goal(f"synthetic {clip.name}: mean IoU (efdm)", value, SYNTHETIC_GOAL))
    clips, where = speed_clips(results)
    efdm_ms, skimage_ms = pooled_median_ms(clips, "efdm"), pooled_median_ms(clips, "skimage")
    speedup = skimage_ms / efdm_ms
    lines.append(
        GoalLine.at_least(
            f"speed-up efdm vs skimage ({where}, median ms/frame)",
            speedup,
            f"{speedup:.1f}x (efdm {efdm_ms:.2f} ms, skimage {skimage_ms:.1f} ms)"
            if math.isfinite(speedup)
            else "-",
            SPEEDUP_GOAL,
            f">= {SPEEDUP_GOAL:g}x",
        )
    )
    fps = 1e3 / efdm_ms
    lines.append(
        GoalLine.at_least(
            f"efdm frames/s ({where}, {NODES} nodes, single thread)",
            fps,
            f"{fps:.0f} fps (median {efdm_ms:.2f} ms)" if math.isfinite(fps) else "-",
            FPS_GOAL,
            f">= {FPS_GOAL:g} fps",
        )
    )
    return lines


def j_cell(clip: ClipResult, tracker: str) -> str:
    """A clip's mean J for one tracker, marked when the tracker failed or was limited."""
    run = clip.runs.get(tracker)
    if run is None:
        return "-"
    mark = " (failed)" if run.error else ""
    limited = f" ({run.frames} fr.)" if run.frames < clip.frames else ""
    return f"{fmt(run.mean_j, '.3f')}{limited}{mark}"


def davis_section(results: Results) -> str:
    """DAVIS mean J per sequence beside the README's reference numbers, and timings."""
    trackers = results.trackers
    refs = list(REFERENCES)
    rows = [
        [
            c.name,
            str(c.frames),
            *(j_cell(c, t) for t in trackers),
            *(fmt(reference(r, c.name), ".3f") for r in refs),
        ]
        for c in results.davis
    ]
    rows.append(
        [
            "**mean**",
            str(sum(c.frames for c in results.davis)),
            *(f"**{fmt(mean_j(results.davis, t), '.3f')}**" for t in trackers),
            *(fmt(reference(r, "mean"), ".3f") for r in refs),
        ]
    )
    headers = ["sequence", "frames", *trackers, *(f"ref. {r}" for r in refs)]
    return "\n\n".join(
        [
            "## DAVIS-2016 (480p): mean J over frames 1..T",
            "`ref.` columns: the reference scores of `../shared/data/davis2016/README.md` "
            "(same protocol, 128 nodes): static, plain edge attraction + EFDM smoothing, rigid "
            "similarity motion (Lucas-Kanade + RANSAC), that + edge snapping (6 px) + EFDM "
            f"smoothing, scikit-image active_contour. Goal: efdm mean J >= {DAVIS_GOAL:g}.",
            md_table(headers, rows),
            "### Time per frame (median ms over frames 1..T; step calls only, one thread)",
            timing_table(results.davis, trackers),
        ]
    )


def timing_table(clips: Sequence[ClipResult], trackers: Sequence[str]) -> str:
    """Median ms per frame per tracker, efdm frames/s and speed-up against skimage."""
    rows: list[list[str]] = []
    for clip in [*clips, None]:
        chosen = list(clips) if clip is None else [clip]
        medians = {t: pooled_median_ms(chosen, t) for t in trackers}
        efdm = medians.get("efdm", math.nan)
        rows.append(
            [
                "**all frames**" if clip is None else clip.name,
                *(fmt(medians[t], ".2f") for t in trackers),
                fmt(1e3 / efdm, ".0f"),
                fmt(medians.get("skimage", math.nan) / efdm, ".1f"),
            ]
        )
    return md_table(["clip", *(f"{t} ms" for t in trackers), "efdm fps", "skimage/efdm"], rows)


def synthetic_section(results: Results) -> str:
    """Mean IoU per synthetic condition, and timings."""
    trackers = results.trackers
    rows = [
        [c.name, str(c.frames), *(j_cell(c, t) for t in trackers), goal_verdict(c)]
        for c in results.synthetic
    ]
    limit = results.config.skimage_synthetic
    skimage_note = (
        f" skimage tracks only the first {limit} frames of each condition (it is slow); its J "
        f"is the mean over frames 1..{limit - 1}, not comparable one-to-one with the others."
        if limit is not None and "skimage" in trackers
        else ""
    )
    return "\n\n".join(
        [
            "## Synthetic sequences (`engine.testing.synthetic`): mean IoU over frames 1..T",
            f"Seed 0, 480 x 640, {results.config.synthetic_length} frames per condition. Goal: "
            f"efdm >= {SYNTHETIC_GOAL:g} on every condition.{skimage_note}",
            md_table(["condition", "frames", *trackers, "efdm goal"], rows),
            "### Time per frame (median ms over frames 1..T; step calls only, one thread)",
            timing_table(results.synthetic, trackers),
        ]
    )


def goal_verdict(clip: ClipResult) -> str:
    """PASS / FAIL of the synthetic goal for one condition."""
    run = clip.runs.get("efdm")
    if run is None or math.isnan(run.mean_j):
        return verdict(None)
    return verdict(run.mean_j >= SYNTHETIC_GOAL)


def summary(values: Sequence[float] | None, how: Callable[[Any], Any], spec: str) -> str:
    """``how`` (mean, max, ...) of a diagnostic over frames 1..T, formatted (``-``: none)."""
    if values is None or len(values) < 2:
        return "-"
    return format(float(how(np.asarray(values[1:], dtype=np.float64))), spec)


def diagnostics_section(results: Results) -> str:
    """efdm's own per-frame diagnostics, summarised per clip."""
    rows: list[list[str]] = []
    for clip in [*results.davis, *results.synthetic]:
        run = clip.runs.get("efdm")
        if run is None or not run.ms:
            continue
        extras = run.extras
        rows.append(
            [
                f"{clip.source} {clip.name}",
                fmt(run.ms[0], ".1f"),
                summary(extras.get("iterations"), np.mean, ".1f"),
                summary(extras.get("iterations"), np.max, ".0f"),
                summary(extras.get("converged"), np.mean, ".0%"),
                summary(extras.get("confidence"), np.mean, ".2f"),
                summary(extras.get("confidence"), np.min, ".2f"),
                fmt(min(run.scores, default=math.nan), ".3f"),
            ]
        )
    if not rows:
        return ""
    headers = [
        "clip",
        "frame 0 ms",
        "iter. mean",
        "iter. max",
        "converged",
        "conf. mean",
        "conf. min",
        "worst J",
    ]
    title = "## efdm diagnostics (frames 1..T; frame 0 is the initialisation step)"
    return "\n\n".join([title, md_table(headers, rows)])


def notes_section(results: Results) -> str:
    """Protocol, baseline settings, limits, failures and skipped parts."""
    params = ", ".join(f"{k}={v}" for k, v in SKIMAGE_PARAMS.items())
    lines = [
        "## Notes",
        "",
        f"- Protocol: the first mask's largest outer contour resampled to {NODES} nodes "
        "(`engine.geometry.mask_to_contour`) is the initial contour; trackers then see only "
        "the BGR frames, frame 0 first. J = IoU of the filled contour "
        "(`engine.geometry.contour_to_mask`) with the mask (`engine.geometry.mask_iou`), mean "
        "over frames 1..T per clip, then over clips. A tracker that raises scores 0 on the "
        "frames it did not track.",
        "- Timing: only the `step` calls (frame decoding and scoring excluded), one thread "
        "(`cv2.setNumThreads(1)`; OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS=1), median over frames 1..T "
        "(frame 0 is initialisation). Each tracker tracks a whole clip uninterrupted, as in "
        "use; on each clip the trackers run one after the other, in an order that alternates "
        "from clip to clip so that changes of machine load fall on all of them. (Taking turns "
        "frame by frame, as this benchmark once did, lets the 80 ms skimage step evict efdm's "
        "working set from the caches before every efdm step: about 25 % slower efdm steps.)",
        f"- skimage baseline: `skimage.filters.gaussian(grey, sigma={SKIMAGE_SIGMA:g})` then "
        f"`skimage.segmentation.active_contour(..., {params})`, re-initialised on every frame "
        "from the previous result ((row, col) converted from/to [x, y]); the settings of the "
        "DAVIS README's reference table.",
    ]
    if results.config.name == "quick":
        lines.append("- `--quick` run (smoke test): few sequences, truncated.")
    if results.davis and partial_davis(results):
        lines.append(
            "- `*`: not all five DAVIS sequences in full, so the mean J is not comparable "
            "with the references' mean."
        )
    lines += [f"- {note}" for note in results.notes]
    lines += [f"- tracker `{t}` not run: {why}" for t, why in results.unavailable.items()]
    for clip in [*results.davis, *results.synthetic]:
        lines += [
            f"- `{name}` failed on {clip.source} {clip.name} at {run.error}"
            for name, run in clip.runs.items()
            if run.error
        ]
    return "\n".join(lines)


def render(results: Results) -> str:
    """The whole markdown report."""
    m = results.machine
    top = header(
        "Contour tracking benchmark",
        m,
        f"{m['cpu_count']} CPUs",
        load_line(m, " (timings are only as quiet as the machine)"),
        f"- python {m['python']}, numpy {m['numpy']}, opencv {m['opencv']}, "
        f"scikit-image {m['skimage']}",
        f"- run: `{results.config.name}`, trackers {', '.join(results.trackers) or 'none'}, "
        f"{results.wall_seconds:.0f} s wall time",
    )
    sections = ["\n".join(top), "## Goals\n\n" + goals_table(goals(results))]
    if results.davis:
        sections.append(davis_section(results))
    if results.synthetic:
        sections.append(synthetic_section(results))
    sections += [s for s in (diagnostics_section(results), notes_section(results)) if s]
    if results.sheets:
        sections.append(
            "Contact sheets (every DAVIS sequence; the synthetic conditions where efdm scores "
            "lowest): " + ", ".join(f"`{s}`" for s in results.sheets) + "."
        )
    return "\n\n".join(sections) + "\n"


def clip_json(clip: ClipResult) -> dict[str, Any]:
    """Raw per-frame numbers of one clip (contours left out)."""
    runs = {
        name: {
            "frames_tracked": run.frames,
            "mean_j": finite(run.mean_j),
            "j": run.scores,
            "j_frame0": run.iou[0] if run.iou else None,
            "median_ms": finite(run.median_ms),
            "ms": run.ms,
            "extras": run.extras,
            "error": run.error,
        }
        for name, run in clip.runs.items()
    }
    return {"name": clip.name, "frames": clip.frames, "shape": list(clip.shape), "runs": runs}


def to_json(results: Results) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        **run_json(results),
        "trackers": list(results.trackers),
        "unavailable": results.unavailable,
        "skimage_params": SKIMAGE_PARAMS,
        "goals": goals_json(goals(results)),
        "davis": [clip_json(c) for c in results.davis],
        "synthetic": [clip_json(c) for c in results.synthetic],
        "davis_references": {k: list(v) for k, v in REFERENCES.items()},
        "notes": results.notes,
        "units": {"j": "IoU of frames 1..T", "ms": "milliseconds per step call, frame 0 first"},
    }
