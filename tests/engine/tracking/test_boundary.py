"""engine.tracking.boundary: outward normals and the boundary search along them."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, outward_normals
from engine.tracking.appearance import Histograms
from engine.tracking.boundary import find_boundary
from engine.tracking.maps import Maps, edge_map
from tests.engine.scenes import DiscScene, two_colour_frame

F64 = NDArray[np.float64]
U8 = NDArray[np.uint8]

CENTER, RADIUS = (80.0, 60.0), 25.0
SHAPE = (120, 160)


def radial(nodes: F64, center: tuple[float, float]) -> F64:
    """Unit vectors from ``center`` to each node."""
    d = nodes - np.asarray(center)
    result: F64 = d / np.hypot(d[:, 0], d[:, 1])[:, None]
    return result


@pytest.mark.parametrize("reverse", [False, True], ids=["ccw", "cw"])
def test_outward_normals_of_a_circle_point_away_from_its_centre(reverse: bool) -> None:
    nodes = circle_nodes(CENTER, RADIUS, 48)
    if reverse:
        nodes = nodes[::-1].copy()
    normals = outward_normals(nodes)
    assert normals.shape == nodes.shape
    np.testing.assert_allclose(np.hypot(normals[:, 0], normals[:, 1]), 1.0)
    np.testing.assert_allclose(normals, radial(nodes, CENTER), atol=1e-12)


@pytest.mark.parametrize("reverse", [False, True], ids=["ccw", "cw"])
def test_outward_normals_of_a_square_point_out_of_each_side(reverse: bool) -> None:
    # nodes at the middle of each side of the square [0, 10]^2 (and its corners)
    square = np.array(
        [[0, 0], [5, 0], [10, 0], [10, 5], [10, 10], [5, 10], [0, 10], [0, 5]], dtype=np.float64
    )
    if reverse:
        square = square[::-1].copy()
    normals = outward_normals(square)
    expected = {(5.0, 0.0): [0, -1], (10.0, 5.0): [1, 0], (5.0, 10.0): [0, 1], (0.0, 5.0): [-1, 0]}
    for node, normal in zip(square, normals, strict=True):
        key = (float(node[0]), float(node[1]))
        if key in expected:
            np.testing.assert_allclose(normal, expected[key], atol=1e-12)


def maps_for(frame: U8, *, origin: tuple[int, int] = (0, 0)) -> Maps:
    """Cue maps of ``frame`` (cropped at ``origin``) with a model fit on the true disc."""
    model = Histograms.fit(frame, circle_nodes(CENTER, RADIUS, 64), 15)
    x0, y0 = origin
    crop = frame[y0:, x0:]
    grey = np.asarray(cv2.cvtColor(crop, cv2.COLOR_BGR2GRAY), np.uint8)
    return Maps(origin, model.probability(crop), edge_map(grey))


SCENES = {
    "two-colour": lambda: two_colour_frame(CENTER, RADIUS, SHAPE),
    "textured": lambda: DiscScene(SHAPE[1], SHAPE[0], RADIUS, seed=5).frame(CENTER),
}


@pytest.mark.parametrize("scene", list(SCENES))
@pytest.mark.parametrize("reverse", [False, True], ids=["ccw", "cw"])
@pytest.mark.parametrize(("change", "expected"), [(-5.0, 5.0), (5.0, -5.0), (0.0, 0.0)])
def test_find_boundary_points_to_the_disc_edge(
    scene: str, reverse: bool, change: float, expected: float
) -> None:
    """A contour 5 px inside the disc is pulled out by ~5 px, one outside pulled in."""
    maps = maps_for(SCENES[scene]())
    nodes = circle_nodes(CENTER, RADIUS + change, 64)
    if reverse:
        nodes = nodes[::-1].copy()
    ev = find_boundary(maps, nodes, outward_normals(nodes), 12)
    assert ev.offset.shape == ev.strength.shape == (64,)
    assert ((ev.strength >= 0) & (ev.strength <= 1)).all()
    near = np.abs(ev.offset - expected) <= 1.5
    assert near.mean() >= 0.85, f"offsets {np.percentile(ev.offset, [5, 50, 95])}"
    assert np.median(ev.offset) == pytest.approx(expected, abs=1.0)
    assert (ev.strength > 0.3).mean() >= 0.85
    assert ev.contrast > 0.3


def test_find_boundary_respects_the_maps_origin() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE)
    nodes = circle_nodes(CENTER, RADIUS - 5, 64)
    normals = outward_normals(nodes)
    whole = find_boundary(maps_for(frame), nodes, normals, 12)
    cropped = find_boundary(maps_for(frame, origin=(30, 20)), nodes, normals, 12)
    np.testing.assert_allclose(cropped.offset, whole.offset)
    assert np.median(cropped.offset) == pytest.approx(5.0, abs=1.0)


def test_find_boundary_without_evidence_stays_put_weakly() -> None:
    flat = np.full((*SHAPE, 3), 128, np.uint8)
    model = Histograms.fit(flat, circle_nodes(CENTER, RADIUS, 64), 15)
    maps = Maps((0, 0), model.probability(flat), edge_map(flat[..., 0]))
    nodes = circle_nodes(CENTER, RADIUS, 64)
    ev = find_boundary(maps, nodes, outward_normals(nodes), 12)
    assert np.abs(ev.offset).max() <= 1.0  # the distance penalty keeps it where it is
    assert ev.strength.max() < 0.1
    assert abs(ev.contrast) < 0.01


def test_edge_map_is_scaled_to_unit_range() -> None:
    frame = two_colour_frame(CENTER, RADIUS, SHAPE, noise=0.0)
    edges = edge_map(np.asarray(cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY), np.uint8))
    assert edges.shape == SHAPE
    assert edges.dtype == np.float32
    assert edges.min() >= 0.0
    assert edges.max() <= 1.0
    assert edges[60, 80] == 0.0  # flat inside
    assert edges[60, 80 + 25] > 0.5  # on the rim
    flat = edge_map(np.full(SHAPE, 77, np.uint8))
    assert not flat.any()
