"""engine.tracking._refine_kernel: the compiled refinement loop against the same loop in Python."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine import deform
from engine.geometry import circle_nodes
from engine.physics.recursive import kernel_arguments
from engine.tracking._refine_kernel import refine_chain
from engine.tracking.appearance import Histograms
from engine.tracking.maps import Maps, edge_map
from tests.engine.pulls import boundary_pull
from tests.engine.scenes import DiscScene

F64 = NDArray[np.float64]


def python_loop(
    maps: Maps,
    rest: F64,
    radii: list[int],
    weights: tuple[float, float, float],
    tol: float,
    a: float,
) -> tuple[F64, int, bool, float]:
    x, converged, it, contrast = rest, False, 0, 0.0
    for radius in radii:
        it += 1
        pull, contrast = boundary_pull(
            maps,
            x,
            radius,
            region_weight=weights[0],
            edge_weight=weights[1],
            distance_penalty=weights[2],
        )
        candidate = rest + deform((x - rest) + pull, a)
        moved = float(np.abs(candidate - x).max())
        x = candidate
        if moved < tol:
            converged = True
            break
    return x, it, converged, contrast


@pytest.fixture(scope="module")
def maps() -> Maps:
    scene = DiscScene(160, 120, 24.0, seed=8)
    frame = scene.frame((78.0, 62.0))
    model = Histograms.fit(frame, circle_nodes((78.0, 62.0), 24.0, 64), 12)
    grey = np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8)
    return Maps((10, 4), model.probability(frame[4:, 10:]), edge_map(grey[4:, 10:]))


@pytest.mark.parametrize(
    ("stiffness", "tol", "count"), [(40.0, 0.05, 64), (2.0, 0.05, 48), (400.0, 1e-9, 100)]
)
def test_compiled_loop_equals_the_python_loop(
    maps: Maps, stiffness: float, tol: float, count: int
) -> None:
    rest = circle_nodes((82.0, 58.0), 30.0, count)  # off-centre and too large
    radii = [12, 11, 10, 8, 7, 6, 5, 4, 3, 3]
    weights = (1.0, 0.5, 0.15)
    expected, it, converged, contrast = python_loop(maps, rest, radii, weights, tol, stiffness)
    x = np.empty_like(rest)
    result = refine_chain(
        maps.probability,
        maps.edges,
        maps.edge_step,
        np.asarray(maps.origin, np.float64),
        rest,
        np.asarray(radii, np.int64),
        np.asarray(weights),
        tol,
        np.asarray(kernel_arguments(stiffness, count, True), np.float64),
        x,
        np.zeros(count),
    )
    assert result[0] == it
    assert result[1] == converged
    assert result[2] == pytest.approx(contrast, abs=1e-12)
    np.testing.assert_allclose(x, expected, atol=1e-9)
    assert np.abs(x - rest).max() > 1.0  # the refinement moved the contour


def test_non_finite_forces_stop_without_accepting_the_step(maps: Maps) -> None:
    rest = circle_nodes((82.0, 58.0), 30.0, 32)
    x = np.empty_like(rest)
    solver = np.asarray(kernel_arguments(40.0, 32, True), np.float64)
    solver[1] = np.inf  # 1/s: every displacement overflows
    iterations, converged, _ = refine_chain(
        maps.probability,
        maps.edges,
        maps.edge_step,
        np.zeros(2),
        rest,
        np.full(5, 6, np.int64),
        np.array([1.0, 0.5, 0.15]),
        0.05,
        solver,
        x,
        np.zeros(32),
    )
    assert iterations == 1
    assert not converged
    np.testing.assert_array_equal(x, rest)
