"""The tracking benchmark's scoring of synthetic clips where the object hides."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.common.data import Clip, load_synthetic
from bench.tracking.goals import HIDDEN_FLAGGED_GOAL, SMALL_GOAL, SYNTHETIC_GOAL, accuracy_goals
from bench.tracking.metrics import REACQUIRE_FRAMES, hidden_indices, iou_indices
from bench.tracking.run import ClipResult, TrackRun

T = 20
GAP = range(8, 13)  # frames 8..12 hidden, the object reappears at 13
VISIBLE = tuple(i not in GAP for i in range(T))


def test_hidden_frames_are_scored_by_status_and_iou_resumes_after_three_frames() -> None:
    scored = range(1, T - 1)
    assert hidden_indices(scored, VISIBLE) == list(GAP)
    assert REACQUIRE_FRAMES == 3
    assert iou_indices(scored, VISIBLE) == [*range(1, 8), *range(16, T - 1)]
    assert iou_indices(scored, ()) == list(scored)
    assert hidden_indices(scored, ()) == []


def run(iou: list[float], status: list[str], visible: tuple[bool, ...] = VISIBLE) -> TrackRun:
    return TrackRun("efdm", T, T, iou=iou, status=status, visible=visible)


def test_track_run_scores_hidden_clips() -> None:
    iou = [1.0] * T
    for i in [*GAP, 13, 14, 15]:  # anything there does not count for J
        iou[i] = 0.0
    status = ["tracking"] * T
    status[8:13] = ["lost", "lost", "uncertain", "tracking", "lost"]
    r = run(iou, status)
    assert r.mean_j == 1.0
    assert r.hidden == list(GAP)
    assert r.hidden_flagged == pytest.approx(0.8)
    assert r.status_score.frames == len(r.iou_scored) == 7 + 3
    # an error before the gap: the untracked hidden frames are not flagged
    short = run(iou[:10], status[:10])
    assert short.hidden_flagged == pytest.approx(0.4)
    # a clip without hiding is scored as before
    plain = run([0.5] * T, ["tracking"] * T, ())
    assert plain.mean_j == 0.5
    assert plain.hidden == []
    assert math.isnan(plain.hidden_flagged)


def test_goals_of_hidden_and_small() -> None:
    hidden = run([1.0] * T, ["tracking"] * 8 + ["lost"] * 5 + ["tracking"] * 7)
    small = run([0.9] * T, ["tracking"] * T, ())
    clips = [
        ClipResult("hidden", "synthetic", T, (480, 640), {"efdm": hidden}),
        ClipResult("small", "synthetic", T, (480, 640), {"efdm": small}),
        ClipResult("plain", "synthetic", T, (480, 640), {"efdm": small}),
    ]
    lines = accuracy_goals({}, clips, "plain")
    assert [line.passed for line in lines] == [True, True, True, False]
    assert "hidden frames reported uncertain or lost" in lines[1].goal
    assert lines[1].measured == 1.0
    assert lines[1].target == f">= {100 * HIDDEN_FLAGGED_GOAL:g} %"
    assert lines[2].target == f">= {SMALL_GOAL:g}"
    assert lines[3].target == f">= {SYNTHETIC_GOAL:g}"


def test_clips_carry_visibility() -> None:
    frame = np.zeros((4, 4, 3), np.uint8)
    mask = np.zeros((4, 4), np.uint8)
    assert Clip("a", "davis", (frame, frame), (mask, mask)).visible == (True, True)
    with pytest.raises(ValueError, match="visibility"):
        Clip("a", "davis", (frame, frame), (mask, mask), (True,))
    clip = load_synthetic("hidden", 12)
    assert clip.visible[0]
    assert not all(clip.visible)
    assert all(load_synthetic("plain", 3).visible)
