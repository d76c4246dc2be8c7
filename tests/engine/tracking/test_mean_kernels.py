"""engine.tracking._mean_kernels: numpy's float32 sums and means, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.tracking._mean_kernels import masked_means, mean, pairwise_sum


@settings(max_examples=80, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    count=st.one_of(st.integers(0, 300), st.integers(300, 40_000)),
    spread=st.floats(1e-3, 1e3),
)
def test_the_sum_is_numpys_bit_for_bit(seed: int, count: int, spread: float) -> None:
    """Every branch of the pairwise summation: under 8 values, one block, halvings."""
    values = (np.random.default_rng(seed).standard_normal(count) * spread).astype(np.float32)
    assert pairwise_sum(values) == values.sum()
    if count:
        assert mean(values) == float(values.mean())


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    height=st.integers(1, 120),
    width=st.integers(1, 120),
    share=st.floats(0.01, 1.0),
)
def test_masked_means_are_numpys_bit_for_bit(
    seed: int, height: int, width: int, share: float
) -> None:
    """As the confidence takes them: from a view into a larger map, under two masks."""
    rng = np.random.default_rng(seed)
    whole = rng.random((height + 4, width + 4)).astype(np.float32)
    values = whole[2:-2, 2:-2]  # a view, as the contour's box of the maps
    first, second = rng.random((2, height, width)) < share
    inside, outside = masked_means(values, first, second)
    if first.any():
        assert inside == float(values[first].mean())
    else:
        assert np.isnan(inside)
    if second.any():
        assert outside == float(values[second].mean())
    else:
        assert np.isnan(outside)


def test_a_long_run_of_equal_values_is_exact() -> None:
    """A million ones: where a running sum in float32 would stall at 2^24, the pairwise
    sum is exact, as numpy's is."""
    ones = np.ones(1_000_000, np.float32)
    assert pairwise_sum(ones) == ones.sum() == 1_000_000.0
