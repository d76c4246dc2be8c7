"""The plain tracking run's results (default options): goals, the markdown report, the JSON."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
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
)
from bench.tracking.config import NODES, TIMED_PASSES, Config
from bench.tracking.goals import (
    DEVELOPED_SEEDS,
    accuracy_goals,
    by_condition,
    repeat_goal,
    speed_goals,
)
from bench.tracking.metrics import REACQUIRE_FRAMES, SetScore
from bench.tracking.run import ClipResult, mean_j
from bench.tracking.sets import TITLES, davis_view, is_davis
from bench.tracking.tables import (
    SCORE_HEADERS,
    score_cells,
    seeds_table,
    sequence_table,
    timing_table,
)
from bench.tracking.trackers import SKIMAGE_PARAMS, SKIMAGE_SIGMA

PLAIN = "in-sample: the defaults were chosen on these; --cv gives held-out figures"
"""How the plain run's training figures were obtained: with the defaults, some of
which were chosen by cross-validation on the training set itself."""
REFERENCES: dict[str, tuple[float, ...]] = {
    "static": (0.547, 0.402, 0.325, 0.133, 0.234, 0.328),
    "edge+EFDM": (0.586, 0.501, 0.440, 0.360, 0.259, 0.429),
    "rigid LK": (0.921, 0.777, 0.345, 0.520, 0.233, 0.559),
    "rigid+snap": (0.867, 0.845, 0.384, 0.567, 0.242, 0.581),
    "skimage": (0.087, 0.428, 0.083, 0.146, 0.057, 0.160),
}
"""J of the validation README's reference trackers (blackswan, car-shadow, dog, soapbox,
breakdance, mean), measured over frames 1..T (the last frame counted)."""
TRAIN_REFERENCE = (0.547, 0.291)
"""Mean J and decay of the tracker when the training set arrived (its README; same protocol)."""


@dataclass(slots=True)
class Results:
    """Everything one plain run measured.

    Attributes
    ----------
    sets : dict of str to list of ClipResult
        The clips of every set that ran, in :data:`bench.tracking.config.SETS` order.
    timed : str or None
        The set tracked in this process, alone: the speed figures' clips.
    workers : int
        Worker processes that tracked the other sets.
    partial : tuple of str
        Sets not run in full (``--quick``, ``--sequences``).
    pass_ms : dict of str to list of float
        Each tracker's median ms per frame over the timed set, pass by pass
        (:data:`bench.tracking.config.TIMED_PASSES`).
    repeatable : bool
        Whether every pass over the timed set gave every tracker the same contours.
    """

    config: Config
    trackers: tuple[str, ...]
    sets: dict[str, list[ClipResult]]
    timed: str | None
    workers: int
    machine: dict[str, str]
    wall_seconds: float
    partial: tuple[str, ...] = ()
    notes: list[str] = field(default_factory=list)
    unavailable: dict[str, str] = field(default_factory=dict)
    sheets: list[str] = field(default_factory=list)
    pass_ms: dict[str, list[float]] = field(default_factory=dict)
    repeatable: bool = True

    @property
    def passes(self) -> int:
        """How many times the timed set was tracked (1 when nothing was timed)."""
        return max((len(v) for v in self.pass_ms.values()), default=1)


def efdm_score(clips: Sequence[ClipResult]) -> SetScore:
    """efdm's scores on a set."""
    return SetScore.of(c.runs["efdm"] for c in clips if "efdm" in c.runs)


def speed_where(name: str, resize: float = 1.0) -> str:
    """How the goals name the timed set's frames (DAVIS resized: their lines)."""
    if name == "synthetic":
        return "synthetic 480x640"
    return f"{name} {round(480 * resize)}p"


def goals(results: Results) -> list[GoalLine]:
    """Every goal line: accuracy per set (plain figures), then speed on the timed set."""
    scores = {name: efdm_score(clips) for name, clips in results.sets.items() if clips}
    if "efdm" not in results.trackers:
        scores = {}
    synthetic = results.sets.get("synthetic", [])
    lines = accuracy_goals(scores, synthetic, PLAIN, results.partial)
    if results.timed is not None:
        where = speed_where(results.timed, results.config.davis_resize)
        lines += speed_goals(results.pass_ms, where)
        if results.passes > 1:
            lines.append(repeat_goal(results.repeatable, results.passes, where))
    return lines


def summary_section(results: Results) -> str:
    """efdm's scores per set, beside the baselines' J."""
    others = [t for t in results.trackers if t != "efdm"]
    rows = [
        [
            name + (" *" if name in results.partial else ""),
            *score_cells(efdm_score(clips)),
            *(fmt(mean_j(clips, t), ".3f") for t in others),
        ]
        for name, clips in results.sets.items()
        if clips
    ]
    val = ", ".join(f"{name} {values[-1]:.3f}" for name, values in REFERENCES.items())
    train_j, train_decay = TRAIN_REFERENCE
    return "\n\n".join(
        [
            "## Summary (efdm, frames 1..T-2; the default options)",
            md_table(["set", *SCORE_HEADERS, *(f"{t} J" for t in others)], rows),
            "J: mean over sequences of the per-sequence mean; decay: mean over sequences of "
            "the first quarter's J minus the last quarter's (positive: the track degrades); "
            "the status columns pool every scored frame of the set (in brackets: how many "
            "frames have that IoU). References: the tracker when the training set arrived, "
            f"J {train_j:.3f}, decay +{train_decay:.3f} (`../shared/data/davis2016-train/"
            f"README.md`, same protocol); on the validation five (frames 1..T, the last "
            f"frame counted): {val} (`../shared/data/davis2016/README.md`).",
        ]
    )


def _length(results: Results) -> str:
    """`` (synthetic clips of N frames)`` when the synthetic set ran, and `` (DAVIS frames
    resized by F)`` when they were, else nothing."""
    notes = []
    if "synthetic" in results.sets:
        notes.append(f"synthetic clips of {results.config.synthetic_length} frames")
    if any(is_davis(s) for s in results.sets):
        notes.extend(davis_view(results.config))
    return f" ({'; '.join(notes)})" if notes else ""


def seeds_section(results: Results) -> str:
    """The synthetic conditions over their seeds (when a run draws more than one)."""
    rows = by_condition(results.sets.get("synthetic", []))
    if not rows or max(r.seeds for r in rows) < 2:
        return ""
    return "\n\n".join(
        [
            "## synthetic: each condition over its seeds (efdm)",
            f"Seeds 0-{DEVELOPED_SEEDS - 1} are the draws the tracker was developed and "
            f"judged on; from seed {DEVELOPED_SEEDS} on, no setting or design was chosen on "
            "them: how many of those meet the goal is the better guess of how the tracker "
            "does on generated conditions it has not seen (`--seeds N` draws seeds 0..N-1; "
            "`make bench-seeds`: 24).",
            seeds_table(rows),
        ]
    )


def set_section(results: Results, name: str) -> str:
    """One set's per-sequence table, worst efdm J first."""
    clips = results.sets[name]
    others = [t for t in results.trackers if t != "efdm"]
    limit = results.config.skimage_synthetic if name == "synthetic" else None
    note = (
        f" skimage tracks only the first {limit} frames of each condition (it is slow); its J "
        f"is the mean over frames 1..{limit - 1}, not comparable one-to-one with the others."
        if limit is not None and "skimage" in others
        else ""
    )
    return "\n\n".join(
        [
            f"## {name}: {TITLES[name]}",
            f"{len(clips)} clips, worst efdm J first; tracking / uncertain / lost: shares of the "
            "scored frames efdm reported so; then how many of the frames with low (high) IoU "
            f"it reported uncertain or lost (tracking).{note}",
            sequence_table(clips, others),
        ]
    )


def speed_section(results: Results) -> str:
    """Median ms per frame on the timed set."""
    if results.timed is None:
        return ""
    passes = "; ".join(
        f"{t} " + " / ".join(fmt(ms, ".2f") for ms in medians)
        for t, medians in results.pass_ms.items()
    )
    same = "the same contours" if results.repeatable else "DIFFERENT contours"
    return "\n\n".join(
        [
            f"## Speed: {results.timed} (median ms over frames 1..T-1; step calls only, one "
            "thread, tracked in this process with no worker running)",
            f"Tracked {results.passes} times, "
            f"pass by pass (median ms per frame): {passes}; the goals take each tracker's "
            f"fastest pass, and the passes gave {same}.  The table is the first pass.",
            timing_table(results.sets[results.timed], results.trackers),
        ]
    )


def summary(values: Sequence[float] | None, how: Callable[[Any], Any], spec: str) -> str:
    """``how`` (mean, max, ...) of a diagnostic over frames 1..T-1, formatted (``-``: none)."""
    if values is None or len(values) < 2:
        return "-"
    return format(float(how(np.asarray(values[1:], dtype=np.float64))), spec)


def diagnostics_section(results: Results) -> str:
    """efdm's own per-frame diagnostics, summarised per clip."""
    rows: list[list[str]] = []
    for clip in (c for clips in results.sets.values() for c in clips):
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
                fmt(min(run.scores, default=float("nan")), ".3f"),
            ]
        )
    if not rows:
        return ""
    headers = ["clip", "frame 0 ms", "iter. mean", "iter. max", "converged"]
    headers += ["conf. mean", "conf. min", "worst J"]
    title = "## efdm diagnostics (frames 1..T-1; frame 0 is the initialisation step)"
    return "\n\n".join([title, md_table(headers, rows)])


def protocol_notes() -> list[str]:
    """The notes on the protocol and the lost detection (also the CV report's)."""
    return [
        f"- Protocol (DAVIS): the first mask's largest outer contour resampled to {NODES} "
        "nodes (`engine.geometry.mask_to_contour`) is the initial contour; trackers then see "
        "only the BGR frames, frame 0 first. J = IoU of the filled contour "
        "(`engine.geometry.contour_to_mask`) with the mask (`engine.geometry.mask_iou`); the "
        "first and the last frame of each clip are left out (frames 1..T-2 scored), a set's J "
        "is the mean of the per-clip means. Decay: J of the first quarter of the scored frames "
        "(max(1, n // 4) of n) minus that of the last quarter. A tracker that raises scores 0 "
        "on the frames it did not track.",
        "- Hidden object (synthetic `hidden`): the frames where it is entirely hidden are "
        "scored by status only, correct iff efdm reports `uncertain` or `lost` (goal: all of "
        f"them); IoU (J) counts from frame r + {REACQUIRE_FRAMES} on, r the frame where it "
        "reappears, and the lost detection below leaves out the frames not scored by IoU.",
        "- Lost detection: of the scored frames of a set, pooled, the share with IoU < 0.2 "
        "that efdm reported `uncertain` or `lost`, the share with IoU >= 0.6 it reported "
        "`tracking`, and the mean |confidence - IoU|. The confidence model "
        "(`engine/tracking/confidence.py`) was fitted on the thirty training sequences: on "
        "them these figures are in-sample.",
    ]


def notes_section(results: Results) -> str:
    """Protocol, timing, baseline settings, limits, failures and skipped parts."""
    params = ", ".join(f"{k}={v}" for k, v in SKIMAGE_PARAMS.items())
    lines = [
        "## Notes",
        "",
        *protocol_notes(),
        "- Timing: only the `step` calls (frame decoding and scoring excluded), one thread "
        "(`cv2.setNumThreads(1)`; OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS=1). The speed figures "
        "come from one set tracked in this process before any worker starts, each tracker "
        "uninterrupted through a clip, the trackers one after the other in an order that "
        f"alternates from clip to clip, {TIMED_PASSES} times over: each tracker's fastest "
        "pass gives its figures (a slower pass measures the machine's other work, as "
        "`timeit` assumes), and the passes must give the same contours. "
        f"The other sets are tracked by {results.workers} worker "
        "process(es) at once: their times (in the JSON) share the machine and are "
        "indicative only.",
        f"- skimage baseline: `skimage.filters.gaussian(grey, sigma={SKIMAGE_SIGMA:g})` then "
        f"`skimage.segmentation.active_contour(..., {params})`, re-initialised on every frame "
        "from the previous result ((row, col) converted from/to [x, y]); the settings of the "
        "validation README's reference table.",
    ]
    if results.config.name == "quick":
        lines.append("- `--quick` run (smoke test): few sequences, truncated.")
    if results.partial:
        lines.append(
            f"- `*`: {', '.join(results.partial)} not run in full: not comparable with the "
            "goals and references."
        )
    lines += [f"- {note}" for note in results.notes]
    lines += [f"- tracker `{t}` not run: {why}" for t, why in results.unavailable.items()]
    for clip in (c for clips in results.sets.values() for c in clips):
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
        f"sets {', '.join(results.sets) or 'none'}{_length(results)}, "
        f"{results.wall_seconds:.0f} s wall time "
        f"({results.workers} worker process(es); timed set: {results.timed or 'none'})",
    )
    sections = ["\n".join(top), "## Goals\n\n" + goals_table(goals(results))]
    if any(results.sets.values()):
        sections.append(summary_section(results))
    if seeds := seeds_section(results):
        sections.append(seeds)
    sections += [set_section(results, name) for name, clips in results.sets.items() if clips]
    sections += [s for s in (speed_section(results), diagnostics_section(results)) if s]
    sections.append(notes_section(results))
    if results.sheets:
        sections.append(
            "Contact sheets (the DAVIS sequences where efdm scores lowest, training and "
            "validation together, written but kept out of git; the synthetic conditions where "
            "it scores lowest): " + ", ".join(f"`{s}`" for s in results.sheets) + "."
        )
    return "\n\n".join(sections) + "\n"


def clip_json(clip: ClipResult) -> dict[str, Any]:
    """Raw per-frame numbers of one clip (contours left out)."""
    runs = {
        name: {
            "frames_tracked": run.frames,
            "mean_j": finite(run.mean_j),
            "decay": finite(run.decay),
            "iou": run.iou,
            "median_ms": finite(run.median_ms),
            "ms": run.ms,
            "extras": run.extras,
            "status": run.status,
            "error": run.error,
            "hidden_frames": run.hidden,
            "hidden_flagged": finite(run.hidden_flagged),
        }
        for name, run in clip.runs.items()
    }
    return {"name": clip.name, "frames": clip.frames, "shape": list(clip.shape), "runs": runs}


def score_json(score: SetScore) -> dict[str, Any]:
    """A set's scores as JSON data."""
    s = score.status
    return {
        "sequences": score.sequences,
        "mean_j": finite(score.mean_j),
        "decay": finite(score.decay),
        "scored_frames": s.frames,
        "low_iou_frames": s.low,
        "low_iou_uncertain_or_lost": finite(s.flagged),
        "high_iou_frames": s.high,
        "high_iou_tracking": finite(s.kept),
        "mean_abs_confidence_error": finite(s.error),
    }


def to_json(results: Results) -> dict[str, Any]:
    """Everything of the run as plain JSON data."""
    return {
        **run_json(results),
        "trackers": list(results.trackers),
        "unavailable": results.unavailable,
        "timed_set": results.timed,
        "timed_pass_median_ms": {t: [finite(v) for v in ms] for t, ms in results.pass_ms.items()},
        "timed_passes_identical": results.repeatable,
        "workers": results.workers,
        "partial_sets": list(results.partial),
        "skimage_params": SKIMAGE_PARAMS,
        "goals": goals_json(goals(results)),
        "scores": {
            name: {
                "efdm": score_json(efdm_score(clips)),
                **{
                    t: {"mean_j": finite(mean_j(clips, t))} for t in results.trackers if t != "efdm"
                },
            }
            for name, clips in results.sets.items()
        },
        "synthetic_by_condition": [
            {k: finite(v) if isinstance(v, float) else v for k, v in asdict(row).items()}
            for row in by_condition(results.sets.get("synthetic", []))
        ],
        "sets": {name: [clip_json(c) for c in clips] for name, clips in results.sets.items()},
        "davis_val_references": {k: list(v) for k, v in REFERENCES.items()},
        "notes": results.notes,
        "units": {
            "iou": "IoU of every tracked frame, frame 0 first; frames 1..T-2 are scored",
            "ms": "milliseconds per step call, frame 0 first",
        },
    }
