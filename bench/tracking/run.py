"""Running the trackers over clips: per-frame J, status and timings.

Protocol (DAVIS-2016, semi-supervised): the first frame's mask gives the
initial contours, as ``efdm track --init-mask`` takes them: its largest outer
contour resampled to :data:`NODES` nodes, and every other separate piece of at
least :data:`engine.geometry.MIN_PIECE_AREA` pixels at the same node spacing
(:func:`engine.geometry.mask_to_contours`); the tracker then sees only frames.
J of a frame is the IoU of the filled tracked contours with the ground-truth
mask; a clip's score is the mean over frames 1..T-2, less the frames where the
object is hidden (scored by the tracker's status instead) and the first few
after it reappears (:mod:`bench.tracking.metrics`).  Only the ``step`` calls
are timed; each tracker tracks a whole clip uninterrupted, the trackers one
after the other in an order that alternates from clip to clip.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from bench.common.data import Clip
from bench.common.log import log
from bench.tracking.config import NODES
from bench.tracking.metrics import (
    FLAGGED,
    StatusScore,
    decay,
    hidden_indices,
    iou_indices,
    mean,
    scored_indices,
    share,
)
from bench.tracking.trackers import ContourTracker, Factory, Nodes
from engine.geometry import MIN_PIECE_AREA, contour_to_mask, mask_iou, mask_to_contours


@dataclass(slots=True)
class TrackRun:
    """One tracker on one clip.

    Attributes
    ----------
    tracker : str
        Tracker name.
    frames : int
        Frames of the clip the tracker was asked to track (it may be limited).
    total : int
        Frames of the clip.
    iou : list of float
        J of every tracked frame, frame 0 included (the scored frames: :attr:`scored`).
    ms : list of float
        Milliseconds of every ``step`` call, frame 0 (initialisation) included.
    nodes : list of numpy.ndarray
        The contour of every tracked frame (kept for the contact sheets, not in the JSON);
        of the first piece for an object in several.
    others : list of tuple of numpy.ndarray
        The other pieces' contours of every tracked frame (empty tuples for an object in
        one piece).
    extras : dict of str to list of float
        Per-frame diagnostics (efdm).
    status : list of str
        The tracker's own verdict on every tracked frame (efdm; empty for the others).
    error : str or None
        What went wrong, if the tracker raised; the untracked frames then count J = 0.
    visible : tuple of bool
        Whether the object can be seen in each frame of the clip (empty: in every frame).
    """

    tracker: str
    frames: int
    total: int
    iou: list[float] = field(default_factory=list)
    ms: list[float] = field(default_factory=list)
    nodes: list[Nodes] = field(default_factory=list)
    others: list[tuple[Nodes, ...]] = field(default_factory=list)
    extras: dict[str, list[float]] = field(default_factory=dict)
    status: list[str] = field(default_factory=list)
    error: str | None = None
    visible: tuple[bool, ...] = ()

    @property
    def scored(self) -> range:
        """The scored frames: 1..T-2 (1..frames-1 when limited to fewer frames), by IoU
        (:attr:`iou_scored`) or, where the object is hidden, by status (:attr:`hidden`)."""
        return scored_indices(self.frames, self.total)

    @property
    def iou_scored(self) -> list[int]:
        """The scored frames scored by IoU: all of them unless the object hides."""
        return iou_indices(self.scored, self.visible)

    @property
    def hidden(self) -> list[int]:
        """The scored frames where the object is hidden (scored by status)."""
        return hidden_indices(self.scored, self.visible)

    @property
    def scores(self) -> list[float]:
        """J of the frames scored by IoU; frames never tracked because of an error count 0."""
        return [self.iou[i] if i < len(self.iou) else 0.0 for i in self.iou_scored]

    @property
    def mean_j(self) -> float:
        """Mean J over the frames scored by IoU (nan when there are none)."""
        return mean(self.scores)

    @property
    def decay(self) -> float:
        """J of the first quarter of the frames scored by IoU minus that of the last quarter."""
        return decay(self.scores)

    @property
    def hidden_flagged(self) -> float:
        """Share of the hidden frames reported ``uncertain`` or ``lost`` (NaN: none hidden;
        frames untracked because of an error, or without a status, count as not flagged)."""
        flagged = [i < len(self.status) and self.status[i] in FLAGGED for i in self.hidden]
        return share(sum(flagged), len(flagged))

    @property
    def status_score(self) -> StatusScore:
        """The tracker's status and confidence against J, over the frames scored by IoU that
        it tracked."""
        tracked = [i for i in self.iou_scored if i < len(self.iou)]
        confidence = self.extras.get("confidence", [])
        return StatusScore.of_frames(
            [self.iou[i] for i in tracked],
            [self.status[i] for i in tracked if i < len(self.status)],
            [confidence[i] for i in tracked if i < len(confidence)],
        )

    @property
    def step_ms(self) -> list[float]:
        """Milliseconds of the tracking steps proper (frames 1..)."""
        return self.ms[1:]

    @property
    def median_ms(self) -> float:
        """Median milliseconds per frame over frames 1.. (nan if none)."""
        return statistics.median(self.step_ms) if self.step_ms else math.nan


@dataclass(slots=True)
class ClipResult:
    """Every tracker on one clip."""

    name: str
    source: str
    frames: int
    shape: tuple[int, int]
    runs: dict[str, TrackRun]


def initial_contours(clip: Clip, nodes: int = NODES) -> list[Nodes]:
    """The first mask's contours: its largest piece's resampled to ``nodes`` nodes, then
    every other piece of at least :data:`~engine.geometry.MIN_PIECE_AREA` pixels."""
    return mask_to_contours(clip.masks[0], nodes, min_area=MIN_PIECE_AREA)


def filled(contours: Sequence[Nodes], shape: tuple[int, int]) -> NDArray[np.bool_]:
    """The union of the filled contours, an H x W mask."""
    union = np.zeros(shape, dtype=bool)
    for nodes in contours:
        union |= contour_to_mask(nodes, shape) > 0
    return union


def record_step(tracker: ContourTracker, run: TrackRun, clip: Clip, index: int) -> None:
    """Time one ``step`` on frame ``index`` and score its contour into ``run``."""
    frame = clip.frames[index]
    start = time.perf_counter()
    step = tracker.step(frame)
    run.ms.append(1e3 * (time.perf_counter() - start))
    run.iou.append(float(mask_iou(filled(step.contours, clip.shape), clip.masks[index])))
    run.nodes.append(step.nodes)
    run.others.append(step.others)
    if step.status is not None:
        run.status.append(step.status)
    for key, value in step.extras.items():
        run.extras.setdefault(key, []).append(value)


def record_failure(run: TrackRun, clip: Clip, exc: Exception) -> None:
    """Note a tracker's exception in ``run`` (its untracked frames then score 0)."""
    run.error = f"frame {len(run.iou)}: {type(exc).__name__}: {exc}"
    log(f"{clip.source} {clip.name} {run.tracker}: FAILED at {run.error}")


def run_clip(
    clip: Clip,
    factories: Mapping[str, Factory],
    limits: Mapping[str, int],
    *,
    reverse: bool = False,
    label: str = "",
    nodes: int = NODES,
) -> ClipResult:
    """Every tracker on one clip, one after the other; ``limits`` caps the frames of some.

    Each tracker tracks the clip uninterrupted, as it would in use: taking
    turns frame by frame would let the others evict its working set from the
    caches between two of its frames, which costs a fast tracker the most.
    The order alternates from clip to clip (``reverse``) so that slow changes
    of the machine's load fall on every tracker alike.  Exceptions raised by
    a tracker are recorded in :attr:`TrackRun.error` and end that tracker's
    run on this clip.  ``label`` ends the progress lines (e.g. the options);
    ``nodes`` is the node count of the initial contour (of the largest piece).
    """
    total = len(clip.frames)
    runs = {
        name: TrackRun(name, min(limits.get(name, total), total), total, visible=clip.visible)
        for name in factories
    }
    names = list(factories)[::-1] if reverse else list(factories)
    for name in names:
        run = runs[name]
        try:
            tracker = factories[name](initial_contours(clip, nodes))
        except Exception as exc:  # a crashing tracker is a result, not a reason to stop
            record_failure(run, clip, exc)
            continue
        for index in range(run.frames):
            try:
                record_step(tracker, run, clip, index)
            except Exception as exc:  # idem
                record_failure(run, clip, exc)
                break
    for run in runs.values():
        log(
            f"{clip.source:>11} {clip.name:<18} {run.tracker:<8} J {run.mean_j:.3f}  "
            f"median {run.median_ms:8.2f} ms/frame  ({run.frames} frames){label}"
        )
    return ClipResult(clip.name, clip.source, total, clip.shape, runs)


def pooled_median_ms(results: Sequence[ClipResult], tracker: str) -> float:
    """Median milliseconds per frame over every step (frames 1..) of ``tracker``."""
    samples = [ms for r in results if tracker in r.runs for ms in r.runs[tracker].step_ms]
    return statistics.median(samples) if samples else math.nan


def same_tracks(first: Sequence[ClipResult], second: Sequence[ClipResult]) -> bool:
    """Whether two passes over the same clips gave every tracker the same contours, bit for bit."""
    if [c.name for c in first] != [c.name for c in second]:
        return False
    for a, b in zip(first, second, strict=True):
        if a.runs.keys() != b.runs.keys():
            return False
        for name, run in a.runs.items():
            mine, theirs = _contours(run), _contours(b.runs[name])
            if [len(c) for c in mine] != [len(c) for c in theirs]:
                return False
            for x, y in zip(mine, theirs, strict=True):
                if not all(np.array_equal(p, q) for p, q in zip(x, y, strict=True)):
                    return False
    return True


def _contours(run: TrackRun) -> list[list[Nodes]]:
    """Every piece's contour of every tracked frame."""
    others = run.others or [()] * len(run.nodes)
    return [[nodes, *rest] for nodes, rest in zip(run.nodes, others, strict=True)]


def mean_j(results: Sequence[ClipResult], tracker: str) -> float:
    """Mean over clips of the per-clip mean J (nan when the tracker ran on none)."""
    return mean(r.runs[tracker].mean_j for r in results if tracker in r.runs)
