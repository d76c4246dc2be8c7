"""engine.tracking._mean_kernels: numpy's float32 means under masks, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.tracking._mean_kernels import masked_means, masked_values, mean


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
    ones, twos = masked_values(values, first, second)
    np.testing.assert_array_equal(ones, values[first])
    np.testing.assert_array_equal(twos, values[second])
    inside, outside = masked_means(values, first, second)
    if first.any():
        assert inside == float(values[first].mean())
    else:
        assert np.isnan(inside)
    if second.any():
        assert outside == float(values[second].mean())
    else:
        assert np.isnan(outside)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), count=st.integers(1, 40_000))
def test_the_mean_is_numpys_bit_for_bit(seed: int, count: int) -> None:
    values = (np.random.default_rng(seed).standard_normal(count) * 7.0).astype(np.float32)
    assert mean(values) == float(values.mean())
