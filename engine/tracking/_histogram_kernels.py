"""Compiled whole-histogram steps of the global colour model (:mod:`engine.tracking.appearance`).

A colour histogram has 32^3 = 32,768 bins, and numpy's whole-array expressions for its
table and its blend make a temporary array per operation; each of these loops makes one
pass and the result numpy's expression gives, bit for bit (the same operations on each
bin, in the same order, with no fused multiply-add).
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["blended", "odds_table", "shares"]


@nb.njit(cache=True, nogil=True, error_model="numpy")
def odds_table(
    object_hist: NDArray[np.float64], background_hist: NDArray[np.float64], prior: float
) -> NDArray[np.float32]:
    """p(object | bin) = o / (o + b), each histogram plus ``prior`` spread over its bins,
    as float32: numpy's ``(o + prior / n) / ((o + prior / n) + (b + prior / m))``."""
    n, m = object_hist.shape[0], background_hist.shape[0]
    po, pb = prior / n, prior / m
    out = np.empty(n, dtype=np.float32)
    for i in range(n):
        o = object_hist[i] + po
        b = background_hist[i] + pb
        out[i] = o / (o + b)
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def blended(old: NDArray[np.float64], new: NDArray[np.float64], rate: float) -> NDArray[np.float64]:
    """``(1 - rate) * old + rate * new``, or ``old`` itself when ``new`` is all zero
    (nothing was learnt)."""
    if not np.any(new):
        return old
    keep = 1.0 - rate
    out = np.empty_like(old)
    for i in range(old.shape[0]):
        out[i] = keep * old[i] + rate * new[i]
    return out


@nb.njit(cache=True, nogil=True, error_model="numpy")
def shares(counts: NDArray[np.int64]) -> NDArray[np.float64]:
    """Each bin's share of the counts (all zero when there are none): numpy's
    ``c / max(c.sum(), 1.0)`` in float64, whose sum of whole counts is exact in any order."""
    total = 0.0
    for i in range(counts.shape[0]):
        total += float(counts[i])
    total = max(total, 1.0)
    out = np.empty(counts.shape[0], dtype=np.float64)
    for i in range(counts.shape[0]):
        out[i] = float(counts[i]) / total
    return out
