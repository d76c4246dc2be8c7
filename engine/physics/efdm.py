"""EFDM: the paper's explicit solution, evaluated densely (eq. 18-20).

U_i = sum_j G(d_ij) F_j over all node pairs: O(N^2) time, as in the paper,
with the Green's function in its stable form (:func:`engine.physics.green.green_kernel`)
so it is exact for every N.  Rows are processed in blocks, so memory stays
O(N * block) instead of the N x N matrix.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.physics.green import green_kernel

__all__ = ["solve_efdm"]

_BLOCK = 512


def solve_efdm(columns: NDArray[np.float64], a: float, closed: bool) -> NDArray[np.float64]:
    """Dense explicit solution of (I + K) U = F.

    Closed chain (eq. 18): weight G_N(d) with d = min(|i-j|, N-|i-j|).
    Open chain (eq. 19-20): S_ij + P_ij = G_2N(|i-j|) + G_2N(i+j+1), the
    method of images on a ring of 2N nodes (0-based indices).

    Parameters
    ----------
    columns : numpy.ndarray
        Shape (N, k): k force components (x and y of each contour), one per column.
    a : float
        Stiffness ``a = k/m``.
    closed : bool
        Ring or open line.

    Returns
    -------
    numpy.ndarray
        Displacements, shape (N, k).
    """
    n = columns.shape[0]
    g = green_kernel(n, a) if closed else green_kernel(2 * n, a)
    j = np.arange(n)
    out = np.empty_like(columns)
    for start in range(0, n, _BLOCK):
        i = j[start : start + _BLOCK, None]
        # closed: G(d) = G(N - d), so one index covers both directions
        weights = g[(i - j) % n] if closed else g[np.abs(i - j)] + g[i + j + 1]
        out[start : start + _BLOCK] = weights @ columns
    return out
