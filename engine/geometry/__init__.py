"""Contour geometry: validation, resampling, areas, normals, masks, boxes and similarity fits.

All nodes are ``[x, y]`` pixels (x = column, y = row), as in OpenCV; a
pixel's centre has integer coordinates.  Imports OpenCV (not loaded by
``import engine``).
"""

from engine.geometry.contours import (
    MIN_PIECE_AREA,
    Box,
    Nodes,
    any_in_frame,
    as_nodes,
    bounding_box,
    box_outline,
    circle_nodes,
    contour_to_mask,
    extent,
    mask_iou,
    mask_to_contour,
    mask_to_contours,
    nearest,
    outward_normals,
    perimeter,
    polygon_area,
    resample,
    self_intersects,
)
from engine.geometry.similarity import fit_similarity

__all__ = [
    "MIN_PIECE_AREA",
    "Box",
    "Nodes",
    "any_in_frame",
    "as_nodes",
    "bounding_box",
    "box_outline",
    "circle_nodes",
    "contour_to_mask",
    "extent",
    "fit_similarity",
    "mask_iou",
    "mask_to_contour",
    "mask_to_contours",
    "nearest",
    "outward_normals",
    "perimeter",
    "polygon_area",
    "resample",
    "self_intersects",
]
