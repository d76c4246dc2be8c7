"""The tracking benchmark draws each synthetic condition with several seeds."""

from __future__ import annotations

import numpy as np
import pytest

from bench.common.data import load_synthetic, synthetic_condition, synthetic_name
from bench.tracking.config import FULL, QUICK
from bench.tracking.sets import available


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
