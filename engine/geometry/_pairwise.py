"""numpy's pairwise summation, compiled: the same sums, bit for bit.

numpy sums a contiguous float array (``a.sum()``, and so ``a.mean()``) by
``pairwise_sum`` (numpy's ``loops_utils.h``): runs of up to :data:`BLOCK` values in
:data:`LANES` interleaved partial sums, longer runs as the sum of their halves (the
first a multiple of :data:`LANES` long), the total added to the reduction's identity, 0.
A compiled kernel that must give numpy's numbers (a perimeter, a mean that a threshold
reads) sums in that order here, in the array's own precision.
"""

from __future__ import annotations

from typing import Any

import numba as nb
import numpy as np
from numpy.typing import NDArray

__all__ = ["pairwise_sum"]

Floats = NDArray[np.floating[Any]]
"""float32 or float64 values: each summed in its own precision."""

BLOCK = 128
"""numpy's ``PW_BLOCKSIZE``: the longest run summed without halving."""
LANES = 8
"""The partial sums numpy's pairwise summation keeps within a block."""
STACK = 256
"""Entries of :func:`_pairwise`'s stack: each halving adds two (a join and a half) and
there are at most 63 of them for 2^63 values."""


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _block(values: Floats, start: int, count: int) -> np.floating[Any]:
    """numpy's ``pairwise_sum`` of a run of at most :data:`BLOCK` values."""
    total: np.floating[Any] = values.dtype.type(0)
    if count < LANES:
        for i in range(count):
            total += values[start + i]
        return total
    a = values[start : start + count]
    r0, r1, r2, r3, r4, r5, r6, r7 = a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]
    i = LANES
    while i < count - count % LANES:  # eight partial sums, as numpy keeps them
        r0, r1, r2, r3 = r0 + a[i], r1 + a[i + 1], r2 + a[i + 2], r3 + a[i + 3]
        r4, r5, r6, r7 = r4 + a[i + 4], r5 + a[i + 5], r6 + a[i + 6], r7 + a[i + 7]
        i += LANES
    total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < count:
        total += a[i]
        i += 1
    return total


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _pairwise(values: Floats) -> np.floating[Any]:
    """numpy's ``pairwise_sum`` of all ``values``: a run longer than
    :data:`BLOCK` is the sum of its halves (the first a multiple of :data:`LANES` long).
    Walked with a stack, not recursion, which numba's cache does not load safely."""
    starts = np.empty(STACK, np.int64)
    counts = np.empty(STACK, np.int64)
    joins = np.empty(STACK, np.bool_)  # an entry that adds the two sums above it
    sums = np.empty(STACK, values.dtype)
    top, done = 1, 0
    starts[0], counts[0], joins[0] = 0, values.shape[0], False
    while top > 0:
        top -= 1
        start, count = starts[top], counts[top]
        if joins[top]:
            done -= 1
            sums[done - 1] = sums[done - 1] + sums[done]
        elif count <= BLOCK:
            sums[done] = _block(values, start, count)
            done += 1
        else:
            half = count // 2
            half -= half % LANES
            # the join, then the second half, then the first (popped first)
            starts[top], counts[top], joins[top] = start, count, True
            starts[top + 1], counts[top + 1], joins[top + 1] = start + half, count - half, False
            starts[top + 2], counts[top + 2], joins[top + 2] = start, half, False
            top += 3
    total: np.floating[Any] = sums[0]
    return total


@nb.njit(cache=True, nogil=True, error_model="numpy")
def pairwise_sum(values: Floats) -> np.floating[Any]:
    """``values.sum()`` of a 1-D float32 or float64 array, bit for bit."""
    zero = values.dtype.type(0)  # numpy adds the sum to its identity: -0.0 becomes 0.0
    result: np.floating[Any] = zero + _pairwise(values)
    return result
