"""Dense matrices of the chain model, for the modal reference and for tests."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["laplacian", "stiffness_matrix", "system_matrix"]


def laplacian(n: int, *, closed: bool = True) -> NDArray[np.float64]:
    """Graph Laplacian L of a chain of n nodes.

    2 on the diagonal and -1 to each neighbour; for an open chain the two end
    nodes have 1 on the diagonal (free ends).  ``K = a L`` (paper eq. 2, 13).

    Parameters
    ----------
    n : int
        Number of nodes (>= 2).
    closed : bool
        Ring (node n-1 joined to node 0) or open line.

    Returns
    -------
    numpy.ndarray
        Shape (n, n), float64.
    """
    if n < (3 if closed else 2):
        raise ValueError(f"a {'closed' if closed else 'open'} chain of n = {n} nodes is too short")
    lap = 2.0 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1)
    if closed:
        lap[0, -1] -= 1.0
        lap[-1, 0] -= 1.0
    else:
        lap[0, 0] = lap[-1, -1] = 1.0
    return lap


def stiffness_matrix(n: int, a: float, *, closed: bool = True) -> NDArray[np.float64]:
    """Stiffness matrix ``K = a L`` of the chain (paper eq. 2, 13)."""
    return a * laplacian(n, closed=closed)


def system_matrix(n: int, a: float, *, closed: bool = True) -> NDArray[np.float64]:
    """``I + K``, the matrix of the static problem (I + K) U = F (eq. 16)."""
    return np.eye(n) + stiffness_matrix(n, a, closed=closed)
