"""engine.geometry._pairwise: numpy's pairwise summation, bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.geometry._pairwise import pairwise_sum


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    count=st.one_of(st.integers(0, 300), st.integers(300, 40_000)),
    spread=st.floats(1e-3, 1e3),
    precision=st.sampled_from([np.float32, np.float64]),
)
def test_the_sum_is_numpys_bit_for_bit(
    seed: int, count: int, spread: float, precision: type[np.floating[Any]]
) -> None:
    """Every branch of the pairwise summation: under 8 values, one block, halvings."""
    values = (np.random.default_rng(seed).standard_normal(count) * spread).astype(precision)
    assert pairwise_sum(values) == values.sum()


def test_a_long_run_of_equal_values_is_exact() -> None:
    """A million ones, through thirteen halvings: exact, as numpy's sum is."""
    ones = np.ones(1_000_000, np.float32)
    assert pairwise_sum(ones) == ones.sum() == 1_000_000.0


def test_a_sum_of_negative_zeros_is_zero_as_numpys() -> None:
    """numpy adds the sum to its identity, 0: -0.0 becomes 0.0."""
    total = pairwise_sum(np.array([-0.0]))
    assert total == 0.0
    assert not np.signbit(total)
    assert not np.signbit(np.array([-0.0]).sum())
