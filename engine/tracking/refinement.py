"""Per-frame contour refinement: the chain's equilibrium under image forces.

Each node seeks the boundary along its normal on the cue maps
(:mod:`engine.tracking.maps`); the pulls are forces on the chain, whose
equilibrium around the predicted shape, X = X0 + U with (I + K) U = F (paper
eq. 13-16, :func:`engine.deform`), keeps the shape plausible through noise,
clutter and occlusion (docs/math.md, "Use in the tracker").

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from engine.geometry import resample
from engine.physics.recursive import kernel_arguments
from engine.tracking.maps import Maps
from engine.tracking.options import TrackerOptions
from engine.tracking.validity import valid_contour

__all__ = ["FINAL_RADIUS", "Refinement", "refine", "search_radii"]

FINAL_RADIUS = 3
"""The search radius shrinks to 3 pixels over the iterations: the last
iterations only settle each node on its edge, they do not jump to another."""


@dataclass(frozen=True, slots=True)
class Refinement:
    """Outcome of :func:`refine`.

    Attributes
    ----------
    nodes : numpy.ndarray
        (N, 2) float64 refined contour, ``[x, y]`` pixels, resampled by arc
        length (or the fallback contour when the refinement was invalid).
    iterations : int
        Refinement iterations run.
    converged : bool
        Whether no node moved more than the tolerance in the last iteration.
    contrast : float
        Boundary evidence, >= 0 (0 when the refinement was rejected).
    """

    nodes: NDArray[np.float64]
    iterations: int
    converged: bool
    contrast: float


def search_radii(options: TrackerOptions) -> NDArray[np.int64]:
    """Search radius of each iteration: from ``search_radius`` down to :data:`FINAL_RADIUS`."""
    steps = options.iterations
    radii = [
        max(FINAL_RADIUS, round(options.search_radius * (1.0 - k / steps))) for k in range(steps)
    ]
    return np.asarray(radii, dtype=np.int64)


def refine(
    maps: Maps,
    shape: tuple[int, ...],
    rest: NDArray[np.float64],
    *,
    options: TrackerOptions,
    previous_nodes: NDArray[np.float64],
    hold: NDArray[np.float64] | None = None,
) -> Refinement:
    """Equilibrium of the chain around the predicted shape under image forces.

    Iterates X = X0 + U with (I + K) U = F (paper eq. 13-16), where X0 =
    ``rest`` and F = (X - X0) + pull: the fixed point K (X - X0) = pull
    bends the chain away from the predicted shape only as far as the image
    forces pay for it.  The equilibrium is the exact O(N) solution of
    :func:`engine.deform`, compiled with the boundary search into one call
    (:mod:`engine.tracking._refine_kernel`).

    Parameters
    ----------
    maps : Maps
        The frame's cue maps (of a :class:`~engine.tracking.BoundaryCues`).
    shape : tuple of int
        Shape of the frame (height first).
    rest : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, the predicted contour X0.
    options : TrackerOptions
        Search radius, iterations, tolerance, cue weights and stiffness.
    previous_nodes : numpy.ndarray
        (M, 2) ``[x, y]`` pixels, the contour in the previous frame: the
        reference of :func:`valid_contour` and the last-resort result.
    hold : numpy.ndarray, optional
        (N,) per node of ``rest``, in [0, 1]: how far the node holds its
        place where both sides look alike (:mod:`engine.tracking.holding`);
        None: 0 for every node.

    Returns
    -------
    Refinement
        The resampled contour, or ``rest`` (if valid without the crossing
        check), else ``previous_nodes``, with zero contrast when the refined
        contour is not valid.
    """
    from engine.tracking._refine_kernel import refine_chain

    x = np.empty_like(rest)
    it, converged, contrast = refine_chain(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        np.ascontiguousarray(maps.edges, dtype=np.float32),
        maps.edge_step,
        np.asarray(maps.origin, dtype=np.float64),
        np.ascontiguousarray(rest, dtype=np.float64),
        search_radii(options),
        np.array([options.region_weight, options.edge_weight, options.distance_penalty]),
        options.tolerance,
        np.asarray(kernel_arguments(options.stiffness, len(rest), True), dtype=np.float64),
        x,
        np.zeros(len(rest)) if hold is None else np.ascontiguousarray(hold, dtype=np.float64),
    )
    out = resample(x, len(x))
    if not valid_contour(out, shape, previous_nodes):
        if valid_contour(rest, shape, previous_nodes, check_crossing=False):
            out = rest
        else:
            out = previous_nodes
        contrast = 0.0
    return Refinement(out, it, converged, max(contrast, 0.0))
