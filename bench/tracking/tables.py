"""The markdown tables of the tracking reports: set scores, per-sequence scores, timings."""

from __future__ import annotations

import math
from collections.abc import Sequence

from bench.common.report import fmt, md_table
from bench.tracking.goals import DEVELOPED_SEEDS, ConditionSeeds
from bench.tracking.metrics import HIGH_IOU, LOW_IOU, SetScore, StatusScore, share
from bench.tracking.run import ClipResult, TrackRun, pooled_median_ms

SCORE_HEADERS = (
    "sequences",
    "scored frames",
    "J",
    "decay",
    f"IoU < {LOW_IOU:g}: uncertain/lost",
    f"IoU >= {HIGH_IOU:g}: tracking",
    "mean abs(conf. - IoU)",
)
RUN_HEADERS = (
    "J",
    "decay",
    "tracking",
    "uncertain",
    "lost",
    f"IoU < {LOW_IOU:g}: unc./lost",
    f"IoU >= {HIGH_IOU:g}: tracking",
    "abs(conf. - IoU)",
)


def percent(value: float) -> str:
    """A share as ``97.4 %`` (``-`` when not measured)."""
    return f"{fmt(100 * value, '.1f')} %" if math.isfinite(value) else "-"


def of(part: int, whole: int) -> str:
    """``12/13`` (``-`` for none)."""
    return f"{part}/{whole}" if whole else "-"


def score_cells(score: SetScore) -> list[str]:
    """A set's cells under :data:`SCORE_HEADERS`."""
    status = score.status
    return [
        str(score.sequences),
        str(status.frames) if status.frames else "-",
        fmt(score.mean_j, ".3f"),
        fmt(score.decay, "+.3f"),
        f"{percent(status.flagged)} ({status.low})",
        f"{percent(status.kept)} ({status.high})",
        fmt(status.error, ".3f"),
    ]


def status_cells(status: StatusScore) -> list[str]:
    """Shares of the frames reported tracking / uncertain / lost, and how they match the IoU."""
    return [
        percent(share(status.tracking, status.frames)),
        percent(share(status.uncertain, status.frames)),
        percent(share(status.lost, status.frames)),
        of(status.low_flagged, status.low),
        of(status.high_tracking, status.high),
        fmt(status.error, ".3f"),
    ]


def run_cells(run: TrackRun | None) -> list[str]:
    """One sequence's cells under :data:`RUN_HEADERS`."""
    if run is None:
        return ["-"] * len(RUN_HEADERS)
    mark = " (failed)" if run.error else ""
    return [fmt(run.mean_j, ".3f") + mark, fmt(run.decay, "+.3f"), *status_cells(run.status_score)]


def j_cell(clip: ClipResult, tracker: str) -> str:
    """A clip's J for one tracker, marked when the tracker failed or was limited."""
    run = clip.runs.get(tracker)
    if run is None:
        return "-"
    mark = " (failed)" if run.error else ""
    limited = f" ({run.frames} fr.)" if run.frames < clip.frames else ""
    return f"{fmt(run.mean_j, '.3f')}{limited}{mark}"


def worst_first(clips: Sequence[ClipResult], tracker: str = "efdm") -> list[ClipResult]:
    """Clips by ``tracker``'s J, lowest first (those it did not run on last, in order)."""

    def key(clip: ClipResult) -> float:
        run = clip.runs.get(tracker)
        return run.mean_j if run is not None and math.isfinite(run.mean_j) else math.inf

    return sorted(clips, key=key)


def sequence_table(clips: Sequence[ClipResult], others: Sequence[str]) -> str:
    """Per sequence, worst efdm J first: efdm's scores and status, the ``others``' J."""
    rows = [
        [c.name, str(c.frames), *run_cells(c.runs.get("efdm")), *(j_cell(c, t) for t in others)]
        for c in worst_first(clips)
    ]
    headers = ["sequence", "frames", *(f"efdm {h}" for h in RUN_HEADERS[:2]), *RUN_HEADERS[2:]]
    return md_table([*headers, *(f"{t} J" for t in others)], rows)


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


def seeds_table(rows: Sequence[ConditionSeeds]) -> str:
    """Per synthetic condition: clips meeting the goal (all seeds, then the unseen ones),
    mean and worst IoU."""
    return md_table(
        [
            "condition",
            "goal",
            "seeds",
            "meet the goal",
            f"seeds >= {DEVELOPED_SEEDS}: meet the goal",
            "mean IoU",
            "worst IoU (seed)",
        ],
        [
            [
                r.condition,
                f">= {r.goal:g}",
                str(r.seeds),
                of(r.met, r.seeds),
                of(r.unseen_met, r.unseen),
                fmt(r.mean, ".3f"),
                f"{fmt(r.worst, '.3f')} ({r.worst_seed})",
            ]
            for r in rows
        ],
    )
