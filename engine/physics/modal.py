"""DMMA and DMMAT: the modal reference (Nastar & Ayache; paper eq. 5-16).

K = Phi Omega^2 Phi^T by eigendecomposition, as the paper's baseline does, so
U = Phi (I + Omega^2)^-1 Phi^T F.  O(N^3): a reference to validate and to
benchmark against, not a production solver.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from engine.physics.matrices import stiffness_matrix

__all__ = ["TRUNCATED_FRACTION", "kept_modes", "solve_modal"]

TRUNCATED_FRACTION = 0.25
"""Share of the lowest modes DMMAT keeps (the paper's "25 % of the modes")."""


def kept_modes(eigenvalues: NDArray[np.float64], fraction: float) -> int:
    """How many of the lowest modes to keep for ``fraction`` of them.

    Rounds up so that a degenerate pair (a ring's cos/sin modes share one
    frequency, eq. 8-9) is never split: splitting it would make the result
    depend on the arbitrary basis the eigensolver picked inside the pair.
    """
    n = eigenvalues.shape[0]
    keep = min(n, max(1, math.ceil(fraction * n)))
    scale = max(1.0, float(eigenvalues[-1]))
    while keep < n and eigenvalues[keep] - eigenvalues[keep - 1] <= 1e-9 * scale:
        keep += 1
    return int(keep)


def solve_modal(
    columns: NDArray[np.float64], a: float, closed: bool, fraction: float = 1.0
) -> NDArray[np.float64]:
    """Modal solution of (I + K) U = F, optionally truncated (DMMAT).

    Parameters
    ----------
    columns : numpy.ndarray
        Shape (N, k) force components, one per column.
    a : float
        Stiffness ``a = k/m``.
    closed : bool
        Ring or open line.
    fraction : float
        Share of the lowest-frequency modes kept; 1.0 is DMMA (exact),
        :data:`TRUNCATED_FRACTION` is the paper's DMMAT.

    Returns
    -------
    numpy.ndarray
        Displacements, shape (N, k).
    """
    n = columns.shape[0]
    omega2, phi = np.linalg.eigh(stiffness_matrix(n, a, closed=closed))  # eq. 6
    keep = n if fraction >= 1.0 else kept_modes(omega2, fraction)
    basis = phi[:, :keep]
    amplitudes = (basis.T @ columns) / (1.0 + omega2[:keep, None])  # eq. 14 with I + K
    result: NDArray[np.float64] = basis @ amplitudes  # eq. 5 / 15
    return result
