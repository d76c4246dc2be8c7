"""The tracking benchmark draws each synthetic condition with several seeds."""

from __future__ import annotations

import numpy as np
import pytest

from bench.common.data import load_synthetic, synthetic_condition, synthetic_name
from bench.tracking.config import FULL, QUICK
from bench.tracking.goals import DEVELOPED_SEEDS, by_condition
from bench.tracking.run import ClipResult, TrackRun
from bench.tracking.sets import available
from bench.tracking.tables import seeds_table


@pytest.mark.parametrize(("condition", "seed"), [("occluder", 0), ("occluder", 2), ("small", 11)])
def test_a_clip_name_carries_its_condition_and_seed(condition: str, seed: int) -> None:
    assert synthetic_condition(synthetic_name(condition, seed)) == (condition, seed)


def test_seed_zero_is_the_bare_condition() -> None:
    assert synthetic_name("plain", 0) == "plain"


def test_another_seed_is_another_sequence() -> None:
    first, second = load_synthetic("plain", 3), load_synthetic("plain@1", 3)
    assert second.name == "plain@1"
    assert not np.array_equal(first.masks[0], second.masks[0])


def test_the_full_run_draws_every_condition_with_three_seeds() -> None:
    names, why = available("synthetic", FULL.synthetic_seeds)
    assert why is None
    conditions = {synthetic_condition(name)[0] for name in names}
    assert len(names) == 3 * len(conditions)
    assert QUICK.synthetic_seeds == 1


def _clip(name: str, iou: float, frames: int = 6) -> ClipResult:
    """A synthetic clip on which efdm scored ``iou`` on every frame."""
    run = TrackRun("efdm", frames, frames, iou=[1.0] + [iou] * (frames - 1))
    return ClipResult(name, "synthetic", frames, (48, 64), {"efdm": run})


def test_each_condition_is_summed_up_over_its_seeds() -> None:
    clips = [
        _clip("occluder", 0.99),
        _clip("occluder@1", 0.90),
        _clip("occluder@8", 0.97),
        _clip("occluder@9", 0.60),
        _clip("small", 0.86),
        _clip("small@12", 0.84),
    ]
    occluder, small = by_condition(clips)
    assert (occluder.condition, occluder.goal, occluder.seeds, occluder.met) == (
        "occluder",
        0.95,
        4,
        2,
    )
    assert occluder.mean == pytest.approx((0.99 + 0.90 + 0.97 + 0.60) / 4)
    assert occluder.worst == pytest.approx(0.60)
    assert occluder.worst_seed == 9
    # seeds from DEVELOPED_SEEDS on are counted apart: 8 and 9 here
    assert DEVELOPED_SEEDS == 8
    assert (occluder.unseen, occluder.unseen_met) == (2, 1)
    # "small" has its own, lower goal
    assert (small.goal, small.met, small.unseen, small.unseen_met) == (0.85, 1, 1, 0)


def test_the_report_shows_the_seeds_table_only_for_several_seeds() -> None:
    table = seeds_table(by_condition([_clip("plain", 0.99), _clip("plain@10", 0.5)]))
    assert "| plain | >= 0.95 | 2 | 1/2 | 0/1 | 0.745 | 0.500 (10) |" in table
    assert by_condition([_clip("plain", 0.99)])[0].seeds == 1
