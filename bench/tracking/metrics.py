"""The scores of the DAVIS protocol: which frames count, J, decay, and how well efdm's status
and confidence tell a good track from a lost one.

- Scored frames: 1..T-2 of a T-frame sequence (the first frame's mask is given, the last is
  left out, as in the official DAVIS evaluation); a tracker limited to its first F < T - 1
  frames is scored on 1..F-1.
- Hidden objects (a clip's ``visible`` flags; the synthetic ``"hidden"``): a scored frame where
  the object cannot be seen is scored by the tracker's status only, correct iff ``uncertain``
  or ``lost`` (the share of them: "hidden frames flagged"); it and the first
  :data:`REACQUIRE_FRAMES` frames after the object reappears are not scored by IoU.  Clips
  where the object is always visible are scored on all their scored frames.
- J of a sequence: mean IoU over its frames scored by IoU; J of a set: mean of the
  per-sequence means.
- Decay of a sequence: mean J over the first quarter of its scored frames minus that over the
  last quarter (``max(1, n // 4)`` frames of ``n``); positive = the track degrades.  The decay
  of a set is the mean over its sequences.
- Lost detection, over every scored frame of a set pooled: the share of frames with
  IoU < :data:`LOW_IOU` reported ``uncertain`` or ``lost``, the share of frames with
  IoU >= :data:`HIGH_IOU` reported ``tracking``, and the mean |confidence - IoU|.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, fields
from typing import Protocol

import numpy as np

LOW_IOU = 0.2
"""Below this IoU a frame is lost: it should be reported ``uncertain`` or ``lost``."""
HIGH_IOU = 0.6
"""From this IoU a frame is well tracked: it should be reported ``tracking``."""
REACQUIRE_FRAMES = 3
"""Frames from the one where a hidden object reappears (included) not scored by IoU: the
tracker's time to find it again; IoU counts from the third frame after it reappears."""
FLAGGED = frozenset({"uncertain", "lost"})
"""The statuses that say the object is not (surely) tracked: right for a hidden object."""


def scored_indices(tracked: int, total: int) -> range:
    """Frames scored of a ``total``-frame clip when the tracker tracked its first ``tracked``."""
    return range(1, min(tracked, total - 1))


def iou_indices(scored: range, visible: Sequence[bool]) -> list[int]:
    """The scored frames scored by IoU: those where the object is visible, except the first
    :data:`REACQUIRE_FRAMES` after each hidden stretch (``visible`` empty: all visible)."""
    if not visible:
        return list(scored)
    since = REACQUIRE_FRAMES  # frames since the object was last hidden
    keep: set[int] = set()
    for i, seen in enumerate(visible):
        since = since + 1 if seen else 0
        if seen and since > REACQUIRE_FRAMES:
            keep.add(i)
    return [i for i in scored if i in keep]


def hidden_indices(scored: range, visible: Sequence[bool]) -> list[int]:
    """The scored frames where the object cannot be seen (scored by status)."""
    return [i for i in scored if i < len(visible) and not visible[i]]


def mean(values: Iterable[float]) -> float:
    """The mean (NaN for none)."""
    got = list(values)
    return float(np.mean(got)) if got else math.nan


def decay(scores: Sequence[float]) -> float:
    """Mean of the first quarter of ``scores`` minus that of the last quarter (NaN for none)."""
    if not scores:
        return math.nan
    quarter = max(1, len(scores) // 4)
    return mean(scores[:quarter]) - mean(scores[-quarter:])


def share(part: int, whole: int) -> float:
    """``part / whole`` (NaN when ``whole`` is 0)."""
    return part / whole if whole else math.nan


@dataclass(frozen=True, slots=True)
class StatusScore:
    """How a tracker's per-frame status and confidence matched the IoU, over some frames.

    Attributes
    ----------
    frames : int
        Frames with a status.
    tracking, uncertain, lost : int
        Frames reported so.
    low, low_flagged : int
        Frames with IoU < :data:`LOW_IOU`; those of them reported ``uncertain`` or ``lost``.
    high, high_tracking : int
        Frames with IoU >= :data:`HIGH_IOU`; those of them reported ``tracking``.
    confidence_frames : int
        Frames with a confidence.
    error_sum : float
        Sum over those of |confidence - IoU|.
    """

    frames: int = 0
    tracking: int = 0
    uncertain: int = 0
    lost: int = 0
    low: int = 0
    low_flagged: int = 0
    high: int = 0
    high_tracking: int = 0
    confidence_frames: int = 0
    error_sum: float = 0.0

    @classmethod
    def of_frames(
        cls, iou: Sequence[float], status: Sequence[str], confidence: Sequence[float]
    ) -> StatusScore:
        """The score of frames given by their IoU, status and confidence (equally long, or
        status / confidence empty when the tracker reports none)."""
        labelled = list(zip(iou, status, strict=False))
        return cls(
            frames=len(labelled),
            tracking=sum(s == "tracking" for _, s in labelled),
            uncertain=sum(s == "uncertain" for _, s in labelled),
            lost=sum(s == "lost" for _, s in labelled),
            low=sum(j < LOW_IOU for j, _ in labelled),
            low_flagged=sum(j < LOW_IOU and s != "tracking" for j, s in labelled),
            high=sum(j >= HIGH_IOU for j, _ in labelled),
            high_tracking=sum(j >= HIGH_IOU and s == "tracking" for j, s in labelled),
            confidence_frames=len(confidence),
            error_sum=float(sum(abs(c - j) for j, c in zip(iou, confidence, strict=False))),
        )

    def __add__(self, other: StatusScore) -> StatusScore:
        """Both sets of frames pooled."""
        return StatusScore(
            *(getattr(self, f.name) + getattr(other, f.name) for f in fields(StatusScore))
        )

    @property
    def flagged(self) -> float:
        """Share of the frames with IoU < :data:`LOW_IOU` reported ``uncertain`` or ``lost``."""
        return share(self.low_flagged, self.low)

    @property
    def kept(self) -> float:
        """Share of the frames with IoU >= :data:`HIGH_IOU` reported ``tracking``."""
        return share(self.high_tracking, self.high)

    @property
    def error(self) -> float:
        """Mean |confidence - IoU|."""
        return self.error_sum / self.confidence_frames if self.confidence_frames else math.nan


class Scored(Protocol):
    """One tracker's scores on one sequence (:class:`bench.tracking.run.TrackRun`)."""

    @property
    def mean_j(self) -> float:
        """J of the sequence."""

    @property
    def decay(self) -> float:
        """Decay of the sequence."""

    @property
    def status_score(self) -> StatusScore:
        """Status and confidence against IoU over its scored frames."""


@dataclass(frozen=True, slots=True)
class SetScore:
    """A set's scores: J and decay (means over sequences) and the pooled lost detection.

    Attributes
    ----------
    sequences : int
        Sequences scored.
    mean_j, decay : float
        Means over the sequences of their J and decay (NaN for none).
    status : StatusScore
        Every scored frame pooled.
    """

    sequences: int
    mean_j: float
    decay: float
    status: StatusScore

    @classmethod
    def of(cls, runs: Iterable[Scored]) -> SetScore:
        """The scores of the runs of one tracker, one run per sequence."""
        chosen = list(runs)
        status = sum((r.status_score for r in chosen), StatusScore())
        return cls(
            len(chosen),
            mean(r.mean_j for r in chosen),
            mean(r.decay for r in chosen if math.isfinite(r.decay)),
            status,
        )
