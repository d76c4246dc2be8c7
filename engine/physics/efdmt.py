"""EFDMT: the truncated explicit solution (paper eq. 21).

Each node sums the Green's-function weights of its 2M + 1 nearest nodes only.
That is a short convolution, done by :func:`scipy.ndimage.convolve1d` with
periodic extension for a ring and half-sample mirroring for an open chain
(the method of images of eq. 19-20): O(N M) time, no N x N matrix.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.physics.green import green_kernel, paper_radius, tolerance_radius
from engine.physics.recursive import solve_exact

__all__ = ["solve_efdmt", "truncation_radius"]


def truncation_radius(n: int, a: float, tol: float | None) -> int:
    """EFDMT neighbourhood: the paper's M = ceil(mu ln N), or the tolerance's.

    Parameters
    ----------
    n : int
        Number of nodes.
    a : float
        Stiffness ``a = k/m``.
    tol : float or None
        With a tolerance, the smallest M whose error is guaranteed to be at
        most ``tol * max|F|`` (:func:`engine.physics.green.tolerance_radius`).

    Returns
    -------
    int
        M >= 0.
    """
    return paper_radius(n, a) if tol is None else tolerance_radius(a, tol)


def solve_efdmt(
    forces: NDArray[np.float64], a: float, closed: bool, tol: float | None
) -> NDArray[np.float64]:
    """Truncated explicit solution (eq. 21).

    Parameters
    ----------
    forces : numpy.ndarray
        Shape (B, N, 2), ``[x, y]`` columns.
    a : float
        Stiffness ``a = k/m``.
    closed : bool
        Ring or open line.
    tol : float or None
        Error bound relative to ``max|F|``; None uses the paper's M.

    Returns
    -------
    numpy.ndarray
        Displacements, shape (B, N, 2).  When the neighbourhood covers the
        whole (mirrored) ring nothing is truncated and the result is exact.
    """
    from scipy.ndimage import convolve1d

    n = forces.shape[1]
    period = n if closed else 2 * n
    m = truncation_radius(n, a, tol)
    if 2 * m + 1 >= period:
        return solve_exact(forces, a, closed)
    half = green_kernel(m + 1, a, period=period)
    weights = np.concatenate([half[:0:-1], half])
    # ring: periodic; line: half-sample mirror = the 2N-ring of images (eq. 19-20)
    result: NDArray[np.float64] = convolve1d(
        forces, weights, axis=1, mode="wrap" if closed else "reflect"
    )
    return result
