"""The refinement iteration of :func:`engine.tracking.refinement.refine`, compiled (numba).

One call runs every iteration: the boundary pull along the normals
(:func:`engine.tracking._image_kernels.contour_pull`) and the chain's equilibrium
around the predicted shape by the exact O(N) solver
(:func:`engine.physics._kernels.solve_chain`, the recursions of
:mod:`engine.physics.recursive`), without a round trip through Python per iteration.
Imported lazily; numba caches the machine code on disk.
Kernels use numba's ``error_model="numpy"``: no zero-division check in the
loops, so they vectorise (every divisor is non-zero by construction; the
results are bit for bit those of the default model).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from engine.physics._kernels import solve_chain
from engine.tracking._image_kernels import contour_pull


@nb.njit(cache=True, nogil=True, error_model="numpy")
def refine_chain(
    prob: NDArray[np.float32],
    edges: NDArray[np.float32],
    edge_step: int,
    origin: NDArray[np.float64],
    rest: NDArray[np.float64],
    radii: NDArray[np.int64],
    weights: NDArray[np.float64],
    tolerance: float,
    solver: NDArray[np.float64],
    x: NDArray[np.float64],
    relative: NDArray[np.float64],
) -> tuple[int, bool, float]:
    """Iterate X = X0 + U, (I + K) U = (X - X0) + pull(X), on a closed chain.

    Parameters
    ----------
    prob, edges : numpy.ndarray
        The cue maps (float32), their pixel (0, 0) at frame point ``origin``.
    edge_step : int
        ``Maps.edge_step``: 2 when ``edges`` is at half resolution.
    origin : numpy.ndarray
        ``[x, y]`` of the maps' top-left pixel in the frame.
    rest : numpy.ndarray
        (N, 2) predicted contour X0, frame ``[x, y]``.
    radii : numpy.ndarray
        Search radius of each iteration (their count is the iteration limit).
    weights : numpy.ndarray
        ``[region_weight, edge_weight, distance_penalty]``.
    tolerance : float
        Converged when no node moved more than this (pixels).
    solver : numpy.ndarray
        ``[r, 1 / s, r^N, 1 / (1 - r^N), head]`` of
        :func:`engine.physics.recursive.kernel_arguments` (closed chain of N nodes).
    x : numpy.ndarray
        (N, 2) output: the contour after the last accepted iteration.
    relative : numpy.ndarray
        (N,) per node, in [0, 1]: how far its region cue compares the two sides
        with each other (:mod:`engine.tracking.holding`).

    Returns
    -------
    iterations : int
    converged : bool
    contrast : float
        Boundary evidence of the last iteration's search.
    """
    n = rest.shape[0]
    local = np.empty((n, 2))
    pull = np.empty((n, 2))
    forces = np.empty((1, n, 2))
    shift = np.empty((1, n, 2))
    x[:, :] = rest
    head = int(solver[4])
    iterations = 0
    converged = False
    contrast = 0.0
    for k in range(radii.shape[0]):
        iterations = k + 1
        for i in range(n):
            local[i, 0] = x[i, 0] - origin[0]
            local[i, 1] = x[i, 1] - origin[1]
        contrast = contour_pull(
            prob,
            edges,
            edge_step,
            local,
            radii[k],
            weights[0],
            weights[1],
            weights[2],
            pull,
            relative,
        )
        # fixed point: K (X - X0) = pull, the chain bends away from the
        # predicted shape only as far as the image forces pay for it
        for i in range(n):
            for c in range(2):
                forces[0, i, c] = (x[i, c] - rest[i, c]) + pull[i, c]
        ok = solve_chain(forces, solver[0], solver[1], True, solver[2], solver[3], head, shift)
        moved = 0.0
        for i in range(n):
            for c in range(2):
                step = abs(rest[i, c] + shift[0, i, c] - x[i, c])
                ok = ok and math.isfinite(step)
                moved = max(moved, step)
        if not ok:
            break
        for i in range(n):
            for c in range(2):
                x[i, c] = rest[i, c] + shift[0, i, c]
        if moved < tolerance:
            converged = True
            break
    return iterations, converged, contrast
