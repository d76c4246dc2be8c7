"""Per-frame contour refinement of :class:`engine.tracker.Tracker`, as plain functions.

Each node seeks the boundary along its normal on cue maps (colour model and
edges, :mod:`engine.image_forces`); the pulls are forces on the chain, whose
equilibrium around the predicted shape, X = X0 + U with (I + K) U = F (paper
eq. 13-16, :func:`engine.deform`), keeps the shape plausible through noise,
clutter and occlusion.

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TypeAlias

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.appearance import AppearanceModel
from engine.geometry import contour_to_mask, polygon_area, resample, self_intersects
from engine.image_forces import Maps, edge_map
from engine.recursive import kernel_arguments
from engine.tracker_options import TrackerOptions

__all__ = [
    "LocatedProbability",
    "Refinement",
    "Silhouette",
    "cue_maps",
    "refine",
    "roi_box",
    "unoccluded",
    "valid_contour",
]

LocatedProbability: TypeAlias = tuple[tuple[int, int], NDArray[np.uint8]]
"""p(object) as 0-255 over a region of a frame, with the region's ``(x, y)`` origin."""

Silhouette: TypeAlias = tuple[NDArray[np.float64], NDArray[np.float64]]
"""The object's 2 x 3 similarity motion and the previous contour moved by it, ``[x, y]``."""


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
    maps : Maps
        The frame's cue maps to remember for the next frame (occluded
        pixels keep the object's previous probability).
    """

    nodes: NDArray[np.float64]
    iterations: int
    converged: bool
    contrast: float
    maps: Maps


def valid_contour(
    nodes: NDArray[np.float64],
    shape: tuple[int, ...],
    reference: NDArray[np.float64],
    *,
    check_crossing: bool = True,
) -> bool:
    """Finite, not collapsed, not exploded and (optionally) not self-crossing.

    Parameters
    ----------
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, the contour to check.
    shape : tuple of int
        Shape of the frame (height first).
    reference : numpy.ndarray
        (M, 2) ``[x, y]`` pixels, the last accepted contour: ``nodes`` must
        enclose between 0.2 and 25 times its area.
    check_crossing : bool
        Also reject a self-intersecting contour.

    Returns
    -------
    bool
    """
    if not np.isfinite(nodes).all():
        return False
    area = abs(polygon_area(nodes))
    ref = abs(polygon_area(reference))
    extent = float(np.ptp(nodes, axis=0).max())
    if area < 0.2 * ref or area > 25.0 * ref or extent > 4 * max(shape):
        return False
    return not (check_crossing and self_intersects(nodes))


def roi_box(
    shape: tuple[int, ...], nodes: NDArray[np.float64], search_radius: int
) -> tuple[tuple[int, int], tuple[int, int, int, int]]:
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
    h, w = shape[:2]
    margin = 2 * search_radius + 4
    x0, y0 = np.floor(nodes.min(axis=0)).astype(int) - margin
    x1, y1 = np.ceil(nodes.max(axis=0)).astype(int) + margin
    x0, y0 = min(max(int(x0), 0), w - 1), min(max(int(y0), 0), h - 1)
    x1, y1 = max(min(int(x1), w), x0 + 1), max(min(int(y1), h), y0 + 1)
    return (x0, y0), (x0, y0, x1, y1)


def cue_maps(
    model: AppearanceModel,
    image: NDArray[np.uint8],
    grey: NDArray[np.uint8],
    nodes: NDArray[np.float64],
    search_radius: int,
) -> Maps:
    """Object probability and edge maps over the region of interest of ``nodes``.

    Parameters
    ----------
    model : AppearanceModel
        The object's colour model.
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
    probability = model.probability(image[y0:y1, x0:x1])
    if min(region.shape) < 8:
        return Maps(origin, probability, edge_map(region))
    # edges at half resolution: the halving smooths as much as the Gaussian
    # of the full-resolution map did, at a quarter of the pixels
    half = np.asarray(
        cv2.resize(region, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA), np.uint8
    )
    return Maps(origin, probability, edge_map(half, sigma=0.0), edge_step=2)


def unoccluded(
    maps: Maps, previous: LocatedProbability | None, silhouette: Silhouette
) -> tuple[Maps, Maps]:
    """Colour evidence with occluders made neutral (p = 0.5).

    A pixel inside the predicted silhouette whose object-attached place in
    the previous frame (found through the object's similarity motion) was
    object-like, but which now looks like background, is most likely
    covered by something passing in front: it should neither pull the
    contour in nor count as the object's edge.

    Parameters
    ----------
    maps : Maps
        Cue maps of the current frame.
    previous : tuple, optional
        ``((x, y), p)``: p(object) as 0-255 around the contour in the
        previous frame and its origin; without it nothing is changed.
    silhouette : tuple of numpy.ndarray
        ``(motion, rest)``: the 2 x 3 similarity mapping ``[x, y, 1]`` of the
        previous frame to the current one, and the previous contour moved by
        it, (N, 2) ``[x, y]`` pixels.

    Returns
    -------
    refine : Maps
        ``maps`` with the covered pixels at p = 0.5, for the refinement.
    remember : Maps
        ``maps`` with the covered pixels at their previous p(object) (the
        object goes on under the occluder), for the next frame.
        Both are ``maps`` itself when no pixel is covered.
    """
    from engine._image_kernels import occluded

    if previous is None:
        return maps, maps
    motion, rest = silhouette
    (px, py), was_prob = previous
    ox, oy = maps.origin
    h, w = maps.probability.shape
    # current ROI pixel (u, v) -> frame (u + ox, v + oy) -> previous frame via
    # the inverse motion -> previous ROI (subtract (px, py))
    a = np.vstack([motion, [0.0, 0.0, 1.0]])
    inverse = np.linalg.inv(a)
    shift = np.array([[1.0, 0.0, ox], [0.0, 1.0, oy], [0.0, 0.0, 1.0]])
    back = np.array([[1.0, 0.0, -px], [0.0, 1.0, -py], [0.0, 0.0, 1.0]])
    m = np.ascontiguousarray((back @ inverse @ shift)[:2])
    near = np.ones((7, 7), np.uint8)  # three pixels of slack at the rim
    inside = np.asarray(cv2.dilate(contour_to_mask(rest - [ox, oy], (h, w)), near), np.uint8)
    # covered: inside, background-like now (p < 0.35), object-like before (> 166 / 255)
    where, was = occluded(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        inside,
        np.ascontiguousarray(was_prob, dtype=np.uint8),
        m,
        0.35,
        166,
    )
    if len(where) == 0:
        return maps, maps
    prob = maps.probability.copy()
    prob.flat[where] = 0.5
    # what the next frame remembers: the object goes on under the occluder
    memory = maps.probability.copy()
    memory.flat[where] = was
    return (
        Maps(maps.origin, prob, maps.edges, maps.edge_step),
        Maps(maps.origin, memory, maps.edges, maps.edge_step),
    )


def refine(
    image: NDArray[np.uint8],
    grey: NDArray[np.uint8],
    rest: NDArray[np.float64],
    *,
    model: AppearanceModel,
    options: TrackerOptions,
    previous_nodes: NDArray[np.float64],
    previous_probability: LocatedProbability | None = None,
    silhouette: Silhouette | None = None,
) -> Refinement:
    """Equilibrium of the chain around the predicted shape under image forces.

    Iterates X = X0 + U with (I + K) U = F (paper eq. 13-16), where X0 =
    ``rest`` and F = (X - X0) + pull: the fixed point K (X - X0) = pull
    bends the chain away from the predicted shape only as far as the image
    forces pay for it.  The equilibrium is the exact O(N) solution of
    :func:`engine.deform`, compiled with the boundary search into one call
    (:mod:`engine._refine_kernel`).  The search radius
    shrinks from :attr:`TrackerOptions.search_radius` to 3 pixels.

    Parameters
    ----------
    image, grey : numpy.ndarray
        The frame (BGR or grey) and its grey version, uint8.
    rest : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, the predicted contour X0.
    model : AppearanceModel
        The object's colour model.
    options : TrackerOptions
        Search radius, iterations, tolerance, cue weights and stiffness.
    previous_nodes : numpy.ndarray
        (M, 2) ``[x, y]`` pixels, the contour in the previous frame: the
        reference of :func:`valid_contour` and the last-resort result.
    previous_probability : tuple, optional
        p(object) around the contour in the previous frame (see :func:`unoccluded`).
    silhouette : tuple of numpy.ndarray, optional
        The object's similarity motion and the rigidly moved previous contour;
        enables the occlusion handling of :func:`unoccluded`.

    Returns
    -------
    Refinement
        The resampled contour, or ``rest`` (if valid without the crossing
        check), else ``previous_nodes``, with zero contrast when the refined
        contour is not valid.
    """
    maps = cue_maps(model, image, grey, rest, options.search_radius)
    remembered = maps
    if silhouette is not None:
        maps, remembered = unoccluded(maps, previous_probability, silhouette)
    from engine._refine_kernel import refine_chain

    steps = options.iterations
    radii = [max(3, round(options.search_radius * (1.0 - k / steps))) for k in range(steps)]
    x = np.empty_like(rest)
    it, converged, contrast = refine_chain(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        np.ascontiguousarray(maps.edges, dtype=np.float32),
        maps.edge_step,
        np.asarray(maps.origin, dtype=np.float64),
        np.ascontiguousarray(rest, dtype=np.float64),
        np.asarray(radii, dtype=np.int64),
        np.array([options.region_weight, options.edge_weight, options.distance_penalty]),
        options.tolerance,
        np.asarray(kernel_arguments(options.stiffness, len(rest), True), dtype=np.float64),
        x,
    )
    out = resample(x, len(x))
    if not valid_contour(out, grey.shape, previous_nodes):
        if valid_contour(rest, grey.shape, previous_nodes, check_crossing=False):
            out = rest
        else:
            out = previous_nodes
        contrast = 0.0
    return Refinement(out, it, converged, max(contrast, 0.0), remembered)
