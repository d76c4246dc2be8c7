"""engine.tracking._label_kernels: numpy's counts over labels and sampled colours."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from engine.tracking._label_kernels import colour_spread, label_shares


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    height=st.integers(1, 60),
    width=st.integers(1, 60),
    count=st.integers(1, 12),
)
def test_label_shares_are_numpys_bincount(seed: int, height: int, width: int, count: int) -> None:
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, count, (height, width)).astype(np.int32)
    prior = (255 * (rng.random((height, width)) < 0.5)).astype(np.uint8)
    shares, total = label_shares(labels, prior, count)
    np.testing.assert_array_equal(shares, np.bincount(labels[prior > 0], minlength=count))
    assert total == np.count_nonzero(prior)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    height=st.integers(0, 50),
    width=st.integers(0, 50),
    step=st.integers(1, 7),
    tolerance=st.integers(0, 6),
    spread=st.integers(0, 8),
)
def test_colour_spread_is_numpys_sampled_test(
    seed: int, height: int, width: int, step: int, tolerance: int, spread: int
) -> None:
    """Grey pixels with some channels nudged by up to ``spread`` levels."""
    rng = np.random.default_rng(seed)
    grey = rng.integers(8, 248, (height, width, 1))
    image = (grey + rng.integers(-spread, spread + 1, (height, width, 3))).astype(np.uint8)
    sample = image[::step, ::step].astype(np.int16)
    expected = (sample.max(axis=2) - sample.min(axis=2)).max(initial=0) > tolerance
    assert colour_spread(image, step, tolerance) == expected
