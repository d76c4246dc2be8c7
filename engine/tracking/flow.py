"""Dense optical flow around a contour (OpenCV DIS), read at the nodes.

The flow is computed on halved crops (:class:`engine.tracking.motion.FramePair`):
the chain smooths it anyway.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.tracking.motion import MIN_CROP, FramePair

__all__ = ["DEPTH", "FlowField", "dense_flow", "node_flow", "read_flow"]

DIS_MIN_SIDE = 32  # smaller (or very flat) inputs crash OpenCV's DIS
CONTEXT = 48
"""Pixels kept around the contour for the flow.  DIS's coarse-to-fine result
depends on the crop; this one was chosen with the defaults of the tracker."""
DEPTH = 3.0
"""The flow is read 3 pixels inside each node: on the object's own pixels, past
the mixed pixels of the boundary whose flow is half the background's."""


@dataclass(frozen=True, slots=True)
class FlowField:
    """Dense optical flow over the halved crop of :class:`FramePair`.

    Attributes
    ----------
    frames : FramePair
        The crops the flow was computed on (their origin places it in the frame).
    flow : numpy.ndarray
        (h, w, 2) float32 displacement per half-resolution pixel, in
        half-resolution pixels.
    """

    frames: FramePair
    flow: NDArray[np.float32]

    def at(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Displacement (frame pixels) at ``[x, y]`` frame points, bilinear."""
        where = self.frames.to_half(points).astype(np.float32).reshape(-1, 1, 2)
        sampled = cv2.remap(
            self.flow,
            np.ascontiguousarray(where[..., 0]),
            np.ascontiguousarray(where[..., 1]),
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
        result = 2.0 * np.asarray(sampled, np.float64).reshape(-1, 2)
        return np.where(np.isfinite(result), result, 0.0)


def dense_flow(frames: FramePair) -> FlowField | None:
    """OpenCV DIS optical flow (ultrafast preset) between the halved crops.

    Parameters
    ----------
    frames : FramePair
        The previous and current frames around the contour.

    Returns
    -------
    FlowField or None
        None when the crop is smaller than 4 x 4 pixels.
    """
    a, b = frames.half_previous, frames.half_current
    h, w = a.shape
    if min(frames.previous.shape) < MIN_CROP:
        return None
    # pad small crops by replication and crop the flow back
    pad_y, pad_x = max(0, DIS_MIN_SIDE - h), max(0, DIS_MIN_SIDE - w)
    if pad_y or pad_x:
        a = np.asarray(cv2.copyMakeBorder(a, 0, pad_y, 0, pad_x, cv2.BORDER_REPLICATE), np.uint8)
        b = np.asarray(cv2.copyMakeBorder(b, 0, pad_y, 0, pad_x, cv2.BORDER_REPLICATE), np.uint8)
    dis = cv2.DISOpticalFlow.create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST)
    flow = np.asarray(dis.calc(a, b, np.zeros((*a.shape, 2), np.float32)), dtype=np.float32)
    return FlowField(frames, np.ascontiguousarray(flow[:h, :w]))


def node_flow(
    previous: NDArray[np.uint8],
    current: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    inward: NDArray[np.float64],
    *,
    depth: float = DEPTH,
    margin: int = CONTEXT,
) -> NDArray[np.float64]:
    """Dense optical flow (:func:`dense_flow`) read ``depth`` pixels inside each node.

    Parameters
    ----------
    previous, current : numpy.ndarray
        Grey uint8 frames of equal size.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` contour in ``previous``.
    inward : numpy.ndarray
        (N, 2) unit vectors into the object.
    depth : float
        Sampling depth inside the object (pixels).
    margin : int
        Context kept around the contour (frame pixels).

    Returns
    -------
    numpy.ndarray
        (N, 2) displacement of each node from ``previous`` to ``current``.
    """
    field = dense_flow(FramePair.around(previous, current, nodes, margin=margin))
    return read_flow(field, nodes, inward, depth=depth)


def read_flow(
    field: FlowField | None,
    nodes: NDArray[np.float64],
    inward: NDArray[np.float64],
    *,
    depth: float = DEPTH,
) -> NDArray[np.float64]:
    """``field`` read ``depth`` pixels inside each node (zero without a field)."""
    if field is None:
        return np.zeros_like(nodes)
    return field.at(nodes + depth * inward)
