"""Cue maps: the object probability and the edges around a contour.

The refinement (:func:`engine.tracking.refine`) moves each node along its
normal towards the boundary these maps show: the split of the object
probability (region cue) and the grey-level gradient magnitude (the paper's
attraction of nodes to the object's contour, the edge cue).
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import Box, bounding_box

__all__ = ["EDGE_SIGMA", "Maps", "cue_maps", "edge_map", "roi_box"]

EDGE_SIGMA = 1.0
"""Gaussian smoothing (pixels) before the gradient: removes JPEG block edges and
pixel noise while keeping a thin object's two sides apart."""
EDGE_SAMPLE_STEP = 3
"""Every third pixel each way estimates the edge scale: a ninth of the work for
a percentile that moves by less than a percent."""
EDGE_SCALE_QUANTILE = 0.95
"""Edges are measured against the region's strong gradients (its 95th
percentile), so that a low-contrast clip has usable edges too."""
EDGE_SCALE_FLOOR = 32.0
"""Smallest edge scale: a Sobel response of 32 is about 8 grey levels per pixel;
a region whose strong gradients are weaker than that has only noise."""
ROI_SLACK = 4
"""Pixels of the region of interest beyond twice the search radius: room for the
bilinear samples at the end of the longest search."""
HALVE_EDGES_FROM = 8
"""Regions at least this many pixels high and wide get their edges at half
resolution (a quarter of the pixels; the halving smooths as much as
:data:`EDGE_SIGMA` did); smaller ones at full resolution."""

ProbabilityOf = Callable[[NDArray[np.uint8]], NDArray[np.float32]]
"""An appearance model's per-pixel p(object) of an image region."""


@dataclass(frozen=True, slots=True)
class Maps:
    """Cue maps over a region of interest of the frame.

    Attributes
    ----------
    origin : tuple of int
        ``(x, y)`` of the region's top-left pixel in the frame.
    probability : numpy.ndarray
        float32 p(object) per pixel.
    edges : numpy.ndarray
        float32 gradient magnitude scaled to about [0, 1].
    edge_step : int
        1: ``edges`` is on the grid of ``probability``; 2: at half its
        resolution, edge pixel ``u`` covering pixels ``2u`` and ``2u + 1``
        (a ``cv2.INTER_AREA`` halving).
    observed : numpy.ndarray or None
        p(object) as the appearance model sees the pixels, where
        ``probability`` was changed to guide the refinement (occluders made
        neutral); None when it was not.  What the confidence is read from.
    motion : numpy.ndarray or None
        float32 odds ratio ``e^m`` per pixel, ``m`` the log-odds that it moves
        with the object rather than the background
        (:mod:`engine.tracking.motion_contrast`), kept apart
        from ``probability`` for the segmentation to add to its own colour
        models; None when the motion says nothing.
    in_front : bool
        Whether the object is partly behind something: a piece the occlusion
        rule took for covered has colours its surroundings lack
        (:func:`engine.tracking.occlusion.foreign`).  Judged only when
        :attr:`~engine.tracking.options.TrackerOptions.rigid_behind` is on,
        for a prediction bent by the flow (to a rigid one it makes no
        difference).
    """

    origin: tuple[int, int]
    probability: NDArray[np.float32]
    edges: NDArray[np.float32]
    edge_step: int = 1
    observed: NDArray[np.float32] | None = None
    motion: NDArray[np.float32] | None = None
    in_front: bool = False

    @property
    def seen(self) -> NDArray[np.float32]:
        """:attr:`observed` if set, else :attr:`probability`."""
        return self.probability if self.observed is None else self.observed

    def __post_init__(self) -> None:
        if self.edge_step not in (1, 2):
            raise ValueError(f"edge_step must be 1 or 2; got {self.edge_step!r}")


def edge_map(grey: NDArray[np.uint8], sigma: float = EDGE_SIGMA) -> NDArray[np.float32]:
    """Gradient magnitude of the smoothed image, divided by a robust scale.

    Computed in float32 from a contiguous copy: OpenCV's optimised 8-bit
    paths can differ in the last bit with the memory alignment of a crop,
    and tracking should be exactly repeatable.
    """
    from engine.tracking._image_kernels import scale_and_clip, sobel_magnitude

    image = np.ascontiguousarray(grey, dtype=np.float32)
    smooth = cv2.GaussianBlur(image, (0, 0), sigma) if sigma > 0 else image
    mag: NDArray[np.float32] = sobel_magnitude(np.ascontiguousarray(smooth, dtype=np.float32))
    sample = mag[::EDGE_SAMPLE_STEP, ::EDGE_SAMPLE_STEP].ravel()
    k = int(EDGE_SCALE_QUANTILE * (sample.size - 1))
    scale = float(np.partition(sample, k)[k]) if sample.size else 0.0
    scale_and_clip(mag, 1.0 / max(scale, EDGE_SCALE_FLOOR))
    return mag


def roi_box(
    shape: tuple[int, ...], nodes: NDArray[np.float64], search_radius: int
) -> tuple[tuple[int, int], Box]:
    """Region of interest: the nodes' box grown by twice the search radius.

    Parameters
    ----------
    shape : tuple of int
        Shape of the frame (height first).
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels.
    search_radius : int
        :attr:`TrackerOptions.search_radius`, pixels.

    Returns
    -------
    origin : tuple of int
        ``(x, y)`` of the region's top-left pixel.
    box : tuple of int
        ``(x0, y0, x1, y1)``, clipped to the frame and at least one pixel wide
        and high; the region is ``frame[y0:y1, x0:x1]``.
    """
    box = bounding_box(shape, nodes, 2 * search_radius + ROI_SLACK)
    return (box[0], box[1]), box


def cue_maps(
    probability: ProbabilityOf,
    image: NDArray[np.uint8],
    grey: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    search_radius: int,
) -> Maps:
    """Object probability and edge maps over the region of interest of ``nodes``.

    Parameters
    ----------
    probability : callable
        The appearance model's p(object) of an image region
        (:meth:`engine.tracking.AppearanceModel.probability`).
    image, grey : numpy.ndarray
        The frame (BGR or grey) and its grey version, uint8.
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, the contour the region is built around.
    search_radius : int
        :attr:`TrackerOptions.search_radius`, pixels (see :func:`roi_box`).

    Returns
    -------
    Maps
    """
    origin, (x0, y0, x1, y1) = roi_box(grey.shape, nodes, search_radius)
    region = grey[y0:y1, x0:x1]
    object_probability = probability(image[y0:y1, x0:x1])
    if min(region.shape) < HALVE_EDGES_FROM:
        return Maps(origin, object_probability, edge_map(region))
    half = np.asarray(
        cv2.resize(region, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA), np.uint8
    )
    return Maps(origin, object_probability, edge_map(half, sigma=0.0), edge_step=2)
