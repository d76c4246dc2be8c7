"""engine.tracking._histogram_kernels: numpy's whole-histogram expressions, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray

from engine.tracking._histogram_kernels import blended, odds_table, shares
from engine.tracking.appearance import PRIOR, Histograms

BINS = 1 << 15  # 32 levels a channel


def _histogram(seed: int, empty_share: float) -> NDArray[np.float64]:
    """A normalised histogram with a share of empty bins, as learnt ones have."""
    rng = np.random.default_rng(seed)
    h = rng.exponential(1.0, BINS) * (rng.uniform(size=BINS) > empty_share)
    return np.asarray(h / h.sum(), dtype=np.float64)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.0, 0.99), st.floats(0.0, 1.0))
def test_the_table_and_the_blend_are_numpys(seed: int, empty: float, rate: float) -> None:
    o, b = _histogram(seed, empty), _histogram(seed + 1, empty)
    po, pb = o + PRIOR / len(o), b + PRIOR / len(b)
    np.testing.assert_array_equal(odds_table(o, b, PRIOR), np.asarray(po / (po + pb), np.float32))
    np.testing.assert_array_equal(blended(o, b, rate), (1 - rate) * o + rate * b)


def test_nothing_learnt_blends_to_the_old_histogram() -> None:
    o = _histogram(0, 0.5)
    assert blended(o, np.zeros(BINS), 0.05) is o


@pytest.mark.parametrize("total", [0, 1, 12_345])
def test_shares_are_numpys(total: int) -> None:
    counts = np.bincount(np.random.default_rng(total).integers(0, BINS, total), minlength=BINS)
    as_float = counts.astype(np.float64)
    np.testing.assert_array_equal(shares(counts), as_float / max(as_float.sum(), 1.0))


def test_the_table_is_made_once_per_histograms() -> None:
    h = Histograms(_histogram(1, 0.3), _histogram(2, 0.3))
    table = h.table()
    assert h.table() is table
    other = Histograms(h.background_hist, h.object_hist)  # a new model, a new table
    np.testing.assert_allclose(other.table(), 1.0 - table, atol=1e-6)
    assert h == Histograms(h.object_hist, h.background_hist)  # the table is not compared
