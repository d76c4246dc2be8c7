"""The boundary pull of one refinement iteration, called from Python for tests."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from engine.tracking.maps import Maps


def boundary_pull(
    maps: Maps,
    nodes: NDArray[np.float64],
    radius: int,
    *,
    region_weight: float = 1.0,
    edge_weight: float = 0.5,
    distance_penalty: float = 0.15,
) -> tuple[NDArray[np.float64], float]:
    """The compiled ``contour_pull`` the refinement runs: per-node pulls and the contrast."""
    from engine.tracking._image_kernels import contour_pull

    local = np.ascontiguousarray(nodes - np.asarray(maps.origin, dtype=np.float64))
    pull = np.empty_like(local)
    contrast = contour_pull(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        np.ascontiguousarray(maps.edges, dtype=np.float32),
        maps.edge_step,
        local,
        int(radius),
        float(region_weight),
        float(edge_weight),
        float(distance_penalty),
        pull,
        np.zeros(len(local)),
    )
    return pull, float(contrast)
