"""The tracking benchmark starts an object in pieces from every piece, as ``--init-mask`` does."""

from __future__ import annotations

import numpy as np
import pytest

from bench.common.data import Clip
from bench.tracking.run import ClipResult, TrackRun, initial_contours, run_clip, same_tracks
from bench.tracking.trackers import SkimageTracker, StaticTracker, Step, efdm_factory

H, W, T = 96, 128, 4


def two_pieces() -> Clip:
    """A still object in two pieces (a large square and a smaller one) on a textured ground."""
    rng = np.random.default_rng(3)
    frame = rng.integers(0, 60, (H, W, 3), dtype=np.uint8)
    mask = np.zeros((H, W), np.uint8)
    mask[20:60, 10:50] = 255
    mask[40:64, 80:104] = 255
    frame[mask > 0] = (40, 200, 230)
    return Clip("pieces", "davis-val", (frame,) * T, (mask,) * T)


def test_every_piece_of_the_first_mask_starts_a_contour() -> None:
    contours = initial_contours(two_pieces(), 64)
    assert len(contours) == 2
    assert len(contours[0]) == 64  # the largest piece keeps the node count asked for
    assert contours[0][:, 0].mean() < contours[1][:, 0].mean()


def test_a_clip_scores_the_union_of_the_pieces() -> None:
    clip = two_pieces()
    result = run_clip(clip, {"static": StaticTracker, "efdm": efdm_factory()}, {}, nodes=64)
    for name in ("static", "efdm"):
        run = result.runs[name]
        assert run.error is None
        assert [len(o) for o in run.others] == [1] * T
        # the largest piece alone would score 1600 / 2176 = 0.74
        assert run.mean_j > 0.95, name
    assert result.runs["efdm"].status == ["tracking"] * T


def test_skimage_runs_a_snake_a_piece() -> None:
    pytest.importorskip("skimage")
    clip = two_pieces()
    tracker = SkimageTracker(initial_contours(clip, 32))
    steps = [tracker.step(frame) for frame in clip.frames[:2]]
    assert all(len(step.contours) == 2 for step in steps)
    # each snake stays on its own piece (centres at x = 29.5 and 91.5)
    assert abs(steps[1].nodes[:, 0].mean() - 29.5) < 8
    assert abs(steps[1].others[0][:, 0].mean() - 91.5) < 8


def test_step_contours_list_the_first_piece_first() -> None:
    a, b = np.zeros((3, 2)), np.ones((4, 2))
    assert [len(c) for c in Step(a, others=(b,)).contours] == [3, 4]
    assert len(Step(a).contours) == 1


def test_no_initial_contour_is_refused() -> None:
    with pytest.raises(ValueError, match="at least one"):
        StaticTracker([])
    with pytest.raises(ValueError, match="at least one"):
        efdm_factory()([])


def test_passes_differing_only_in_another_piece_are_not_the_same() -> None:
    square = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])

    def clip(shift: float) -> ClipResult:
        run = TrackRun("efdm", 2, 2, nodes=[square] * 2, others=[(square + shift,)] * 2)
        return ClipResult("a", "davis-val", 2, (8, 8), {"efdm": run})

    assert same_tracks([clip(1.0)], [clip(1.0)])
    assert not same_tracks([clip(1.0)], [clip(1.0 + 1e-12)])
