"""engine.tracking.flow and engine.tracking.motion.FramePair: dense flow at nodes, halved crops."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from engine.geometry import circle_nodes, outward_normals
from engine.tracking.flow import dense_flow, node_flow
from engine.tracking.motion import FramePair
from tests.engine.scenes import shifted, textured_frame

U8 = NDArray[np.uint8]
W, H = 200, 150
NODES = circle_nodes((100.0, 75.0), 30.0, 48)


@pytest.fixture(scope="module")
def grey() -> U8:
    return np.asarray(cv2.cvtColor(textured_frame(5, H, W), cv2.COLOR_BGR2GRAY), np.uint8)


def test_frame_pair_crops_around_the_nodes_and_halves(grey: U8) -> None:
    pair = FramePair.around(grey, grey, NODES, margin=10)
    assert pair.origin == (60, 35)
    assert pair.previous.shape == (81, 81)  # 60 px of circle + 2 x 10 margin, inclusive
    np.testing.assert_array_equal(pair.previous, grey[35:116, 60:141])
    assert pair.half_previous.shape == (40, 40)


@pytest.mark.parametrize("where", [(20.0, 30.0), (21.0, 31.0), (57.0, 12.0)])
def test_to_half_maps_a_frame_point_onto_its_half_resolution_pixel(
    where: tuple[float, float],
) -> None:
    # a bright 2 x 2 block whose centre is ``where + 1/2``: halving keeps its
    # mass at one half pixel (even corner) or spreads it evenly over four
    image = np.zeros((64, 80), np.uint8)
    x, y = int(where[0]), int(where[1])
    image[y : y + 2, x : x + 2] = 200
    pair = FramePair.around(
        image, image, np.array([[0.0, 0.0], [79.0, 0.0], [79.0, 63.0]]), margin=0
    )
    half = pair.half_previous.astype(np.float64)
    rows, cols = np.indices(half.shape)
    centroid = np.array([(cols * half).sum(), (rows * half).sum()]) / half.sum()
    np.testing.assert_allclose(pair.to_half(np.array([[x + 0.5, y + 0.5]]))[0], centroid, atol=1e-9)


@pytest.mark.parametrize("shift", [(3.0, -2.0), (-6.5, 4.0), (0.0, 0.0)])
def test_node_flow_reads_a_translation(grey: U8, shift: tuple[float, float]) -> None:
    inward = -outward_normals(NODES)
    flow = node_flow(grey, shifted(grey, *shift), NODES, inward)
    assert flow.shape == NODES.shape
    error = np.hypot(*(flow - np.array(shift)).T)
    assert np.median(error) < 0.5, f"median error {np.median(error):.2f} px"


def test_dense_flow_of_tiny_and_empty_crops() -> None:
    tiny = np.full((3, 3), 100, np.uint8)
    assert (
        dense_flow(
            FramePair.around(tiny, tiny, np.array([[1.0, 1.0], [2.0, 1.0], [1.0, 2.0]]), margin=0)
        )
        is None
    )
    small = textured_frame(1, 40, 40)[..., 0].copy()
    field = dense_flow(
        FramePair.around(
            small, small, np.array([[10.0, 10.0], [30.0, 10.0], [20.0, 30.0]]), margin=4
        )
    )
    assert field is not None
    values = field.at(np.array([[20.0, 20.0], [-50.0, 400.0]]))  # outside: border replicated
    assert values.shape == (2, 2)
    assert np.isfinite(values).all()
    np.testing.assert_allclose(values, 0.0, atol=0.5)
