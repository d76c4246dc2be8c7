"""Compiled inner loop (numba) of the O(N) exact solver.

Imported lazily by :mod:`engine.physics.recursive` so that ``import engine`` stays
light; numba compiles on first use and caches the machine code on disk.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray


@nb.njit(cache=True, nogil=True, fastmath={"contract"})
def solve_chain(
    F: NDArray[np.float64],
    r: float,
    inv_s: float,
    closed: bool,
    r_n: float,
    inv_den: float,
    head: int,
    out: NDArray[np.float64],
) -> bool:
    """Two first-order recursions per contour and coordinate (see recursive.py).

    F and out have shape (B, N, 2).  Returns False when a carry is not finite,
    i.e. when a force was not finite or the result overflowed.
    """
    n_batch, n = F.shape[0], F.shape[1]
    ok = True
    for b in range(n_batch):
        # Weighted sums of the first and last `head` forces: the start values
        # of the recursions (the rest of the periodic sums is below rounding).
        h0 = 0.0
        h1 = 0.0
        t0 = 0.0
        t1 = 0.0
        w = 1.0
        for m in range(head):
            h0 += w * F[b, m, 0]
            h1 += w * F[b, m, 1]
            t0 += w * F[b, n - 1 - m, 0]
            t1 += w * F[b, n - 1 - m, 1]
            w *= r
        if closed:
            c0 = t0 * inv_den
            c1 = t1 * inv_den
            b0 = h0 * inv_den
            b1 = h1 * inv_den
        else:  # mirrored ring of 2N nodes
            c0 = (h0 + r_n * t0) * inv_den
            c1 = (h1 + r_n * t1) * inv_den
            b0 = (t0 + r_n * h0) * inv_den
            b1 = (t1 + r_n * h1) * inv_den
        for i in range(n):
            c0 = F[b, i, 0] + r * c0
            c1 = F[b, i, 1] + r * c1
            out[b, i, 0] = c0
            out[b, i, 1] = c1
        for i in range(n - 1, -1, -1):
            f0 = F[b, i, 0]
            f1 = F[b, i, 1]
            b0 = f0 + r * b0
            b1 = f1 + r * b1
            out[b, i, 0] = (out[b, i, 0] + b0 - f0) * inv_s
            out[b, i, 1] = (out[b, i, 1] + b1 - f1) * inv_s
        if not (
            math.isfinite(c0) and math.isfinite(c1) and math.isfinite(b0) and math.isfinite(b1)
        ):
            ok = False
    return ok
