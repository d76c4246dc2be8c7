"""Contour geometry: resampling, masks, areas, normals, boxes, self-intersection.

All nodes are ``[x, y]`` pixels (x = column, y = row), as in OpenCV; a
pixel's centre has integer coordinates.
"""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "MIN_PIECE_AREA",
    "Box",
    "any_in_frame",
    "as_nodes",
    "bounding_box",
    "box_outline",
    "circle_nodes",
    "contour_to_mask",
    "extent",
    "mask_iou",
    "mask_to_contour",
    "mask_to_contours",
    "nearest",
    "outward_normals",
    "polygon_area",
    "resample",
    "self_intersects",
]

Nodes = NDArray[np.float64]
Box = tuple[int, int, int, int]
"""``(x0, y0, x1, y1)`` pixel edges: the region ``image[y0:y1, x0:x1]``."""


def as_nodes(nodes: ArrayLike, *, min_count: int = 3) -> Nodes:
    """Validate a contour: a finite float64 array of shape (N, 2), N >= min_count."""
    try:
        arr = np.array(nodes, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"nodes must be an array of [x, y] numbers: {exc}") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] < min_count:
        raise ValueError(f"nodes must have shape (N, 2) with N >= {min_count}; got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError("nodes must be finite")
    return arr


def _count(count: Any, least: int) -> int:
    """``count`` as an int of at least ``least``: a whole number (numpy's too), not a bool or
    a float; ValueError otherwise."""
    if isinstance(count, bool) or not isinstance(count, int | np.integer):
        raise ValueError(f"count must be a whole number; got {count!r}")
    if count < least:
        raise ValueError(f"count must be at least {least}; got {count}")
    return int(count)


def circle_nodes(center: ArrayLike, radius: float, count: int) -> Nodes:
    """``count`` nodes evenly spaced on a circle, counter-clockwise on screen.

    Parameters
    ----------
    center : array_like
        ``[x, y]`` pixels.
    radius : float
        Radius in pixels (> 0).
    count : int
        Number of nodes (>= 3).
    """
    cx, cy = (float(v) for v in np.asarray(center, dtype=np.float64).reshape(2))
    count = _count(count, 3)
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise ValueError(f"center must be finite; got {[cx, cy]}")
    if not (0 < radius < math.inf):
        raise ValueError(f"radius must be finite and > 0; got {radius}")
    t = np.linspace(0.0, 2.0 * np.pi, count, endpoint=False)
    return np.stack([cx + radius * np.cos(t), cy - radius * np.sin(t)], axis=1)


def box_outline(box: ArrayLike, count: int) -> Nodes:
    """A closed contour of ``count`` nodes around a box given in pixel edges.

    ``box`` is ``[x0, y0, x1, y1]``, the box of a mask whose pixels span
    columns ``x0 .. x1 - 1`` and rows ``y0 .. y1 - 1``: the outline runs
    through its edge pixels' centres, or along its edges for a box one pixel
    thin (so that it still encloses an area).

    Raises
    ------
    ValueError
        Unless x1 > x0 and y1 > y0, all finite, and ``count`` >= 3.
    """
    x0, y0, x1, y1 = (float(v) for v in np.asarray(box, dtype=np.float64).reshape(4))
    count = _count(count, 3)
    if not (np.isfinite([x0, y0, x1, y1]).all() and x1 > x0 and y1 > y0):
        raise ValueError("box must be finite [x0, y0, x1, y1] with x1 > x0, y1 > y0")
    right, bottom = x1 - 1.0, y1 - 1.0
    if right <= x0 or bottom <= y0:
        right, bottom = x1, y1
    corners = np.array([[x0, y0], [right, y0], [right, bottom], [x0, bottom]])
    return resample(corners, count, closed=True)


def resample(nodes: Nodes, count: int, *, closed: bool = True) -> Nodes:
    """Nodes evenly spaced by arc length along the polyline through ``nodes``.

    Duplicate consecutive nodes are harmless.  A contour of zero length
    returns ``count`` copies of its first node.

    Parameters
    ----------
    nodes : numpy.ndarray
        Shape (N, 2), ``[x, y]``.
    count : int
        Number of output nodes.
    closed : bool
        Whether the last node joins the first.
    """
    count = _count(count, 1)
    points = np.ascontiguousarray(nodes, dtype=np.float64)
    if points.ndim == 2 and len(points) >= 2 and np.isfinite(points).all():
        from engine.geometry._kernels import resample_polyline

        resampled: Nodes = resample_polyline(points, count, closed)
        return resampled
    pts = np.vstack([nodes, nodes[:1]]) if closed else nodes
    seg = np.hypot(*np.diff(pts, axis=0).T)
    arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = arc[-1]
    if not total > 0:
        return np.repeat(nodes[:1], count, axis=0).astype(np.float64)
    targets = np.linspace(0.0, total, count, endpoint=not closed)
    return np.stack([np.interp(targets, arc, pts[:, 0]), np.interp(targets, arc, pts[:, 1])], 1)


def polygon_area(nodes: Nodes) -> float:
    """Signed area (shoelace); positive when counter-clockwise in x-right, y-up axes
    (0 for no nodes)."""
    if len(nodes) == 0:
        return 0.0
    x, y = nodes[:, 0], nodes[:, 1]
    inner = float(np.dot(x[:-1], y[1:]) - np.dot(y[:-1], x[1:]))
    return 0.5 * (inner + float(x[-1] * y[0] - y[-1] * x[0]))


def perimeter(nodes: Nodes) -> float:
    """Length (pixels) of the closed polygon through ``nodes``, the closing edge included
    (0 for no nodes).  One compiled pass, with numpy's summation: the same number as
    ``norm(diff(closed), axis=1).sum()``, in 1.5 instead of 6.6 µs for 128 nodes."""
    from engine.geometry._kernels import perimeter as length

    pts = np.ascontiguousarray(nodes, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"nodes must be (N, 2) [x, y] points; got shape {pts.shape}")
    return float(length(pts)) if len(pts) else 0.0


def self_intersects(nodes: Nodes, *, closed: bool = True) -> bool:
    """Whether two non-adjacent edges of the polyline properly cross.

    O(N^2) pairs in a compiled loop that stops at the first crossing.
    """
    from engine.geometry._kernels import polyline_crosses

    pts = np.ascontiguousarray(nodes, dtype=np.float64)
    if len(pts) < (4 if closed else 3):
        return False
    return bool(polyline_crosses(pts, closed))


def outward_normals(nodes: Nodes) -> Nodes:
    """Unit normals of a closed contour pointing out of its interior.

    The normal of node i is perpendicular to ``nodes[i + 1] - nodes[i - 1]``.
    In image axes (y down) a clockwise-on-screen contour has positive
    shoelace area, and (t_y, -t_x) points out of it.  One compiled pass.
    """
    from engine.geometry._kernels import outward_normals as normals

    result: Nodes = normals(np.ascontiguousarray(nodes, dtype=np.float64))
    return result


def nearest(queries: Nodes, points: Nodes) -> NDArray[np.int64]:
    """Index of the nearest of ``points`` to each of ``queries`` (both (K, 2) ``[x, y]``).

    Compiled: a few hundred points or more are swept in x order from each query's own
    x, stopping where the x distance alone is farther than the best found (for 128
    nodes among 512, 8 against 40 µs alone and 27-31 against 39-43 µs within the
    tracker's frames; building a k-d tree would cost more than either); fewer are all
    read.  Ties go to the lowest index, as in a full scan.

    Raises
    ------
    ValueError
        If either is not (K, 2), or ``points`` is empty.
    """
    from engine.geometry._kernels import nearest as find

    q = np.ascontiguousarray(queries, dtype=np.float64)
    p = np.ascontiguousarray(points, dtype=np.float64)
    for name, arr in (("queries", q), ("points", p)):
        if arr.ndim != 2 or arr.shape[1] != 2:
            raise ValueError(f"{name} must be (K, 2) [x, y] points; got shape {arr.shape}")
    if len(p) == 0:
        raise ValueError("points is empty: there is no nearest point")
    result: NDArray[np.int64] = find(q, p)
    return result


def any_in_frame(nodes: Nodes, shape: tuple[int, ...]) -> bool:
    """Whether a node of ``nodes`` (``[x, y]``) lies in a frame of ``shape`` (height first):
    a contour with none in it, beside the frame or around all of it, shows none of its
    boundary."""
    h, w = shape[0], shape[1]
    x, y = nodes[:, 0], nodes[:, 1]
    return bool(np.any((x >= 0) & (y >= 0) & (x < w) & (y < h)))


def extent(nodes: Nodes) -> tuple[float, float, float, float]:
    """``(min x, min y, max x, max y)`` of (N, 2) ``[x, y]`` points, in one compiled pass.

    The same numbers as numpy's ``nodes.min(axis=0)`` and ``nodes.max(axis=0)`` (all
    NaN if a node is), at a twentieth of their cost on a contour's few hundred nodes.

    Raises
    ------
    ValueError
        If ``nodes`` is not (N, 2) with N >= 1.
    """
    from engine.geometry._kernels import extent as span

    pts = np.ascontiguousarray(nodes, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) == 0:
        raise ValueError(f"nodes must be (N >= 1, 2) [x, y] points; got shape {pts.shape}")
    return span(pts)


def bounding_box(
    shape: tuple[int, ...],
    nodes: Nodes,
    before: int,
    after: int | None = None,
    *,
    keep_inside: bool = True,
) -> Box:
    """The nodes' pixel box grown by margins and clipped to an image.

    Parameters
    ----------
    shape : tuple of int
        Shape of the image (height first).
    nodes : numpy.ndarray
        (N, 2) ``[x, y]`` pixels, N >= 1.
    before : int
        Pixels added before ``floor`` of the nodes' smallest x and y.
    after : int, optional
        Pixels added after ``ceil`` of their largest x and y (default
        ``before``); the box's end is exclusive, so ``after = before + 1``
        keeps ``before`` whole pixels beyond a node on a pixel centre.
    keep_inside : bool
        True: the box starts inside the image and is at least one pixel
        wide and high, even for nodes wholly outside it.  False: a plain
        clip, which is empty (``x1 <= x0`` or ``y1 <= y0``) when the grown
        box misses the image.

    Returns
    -------
    tuple of int
        ``(x0, y0, x1, y1)``: the region ``image[y0:y1, x0:x1]``.

    Raises
    ------
    ValueError
        If there are no nodes, or one is NaN (an infinite one: OverflowError).
    """
    from engine.geometry._kernels import extent

    if len(nodes) == 0:
        raise ValueError("nodes is empty: there is no box around them")
    h, w = shape[:2]
    grow = before if after is None else after
    low_x, low_y, high_x, high_y = extent(np.ascontiguousarray(nodes, dtype=np.float64))
    x0, y0 = math.floor(low_x) - before, math.floor(low_y) - before
    x1, y1 = math.ceil(high_x) + grow, math.ceil(high_y) + grow
    if not keep_inside:
        return max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
    x0, y0 = min(max(x0, 0), w - 1), min(max(y0, 0), h - 1)
    return x0, y0, max(min(x1, w), x0 + 1), max(min(y1, h), y0 + 1)


def contour_to_mask(nodes: Nodes, shape: tuple[int, ...]) -> NDArray[np.uint8]:
    """Fill a closed contour into a uint8 mask (0 / 255) of ``shape[:2]``.

    Rasterised as :func:`cv2.fillPoly` does (vertices to 1/16 pixel): the
    pixels whose centres lie inside and every pixel the outline passes
    through, so the mask reaches about half a pixel beyond the polygon.  The
    DAVIS reference scores this project quotes were computed with the same
    rule (our static baseline reproduces them exactly), so we keep it.
    """
    from engine.geometry._kernels import fixed_point

    mask = np.zeros(shape[:2], dtype=np.uint8)
    if len(nodes) >= 3:
        # vertices to 1/16 pixel, kept within OpenCV's coordinate range; none if any is
        # not finite
        scaled = fixed_point(np.ascontiguousarray(nodes, dtype=np.float64), 1 << _SHIFT, 1e6)
        if len(scaled):
            cv2.fillPoly(mask, [scaled], 255, lineType=cv2.LINE_8, shift=_SHIFT)
    return mask


_SHIFT = 4
"""Fractional bits of :func:`contour_to_mask`'s vertices (OpenCV's ``shift``): 1/16 pixel."""


def mask_to_contour(mask: ArrayLike, count: int, *, offset: tuple[int, int] = (0, 0)) -> Nodes:
    """The largest outer contour of a binary mask, resampled to ``count`` nodes.

    Parameters
    ----------
    mask : array_like
        H x W, non-zero = object.
    count : int
        Number of nodes (>= 3).
    offset : tuple of int, default (0, 0)
        ``[x, y]`` pixels added to the outline's pixel positions before it is
        resampled: the mask is a crop whose top-left pixel is at ``offset`` in a
        larger image, and the contour is wanted in that image's pixels, exactly as
        the uncropped mask would give it (the integer positions are moved, not the
        resampled floats, whose rounding would then differ).

    Raises
    ------
    ValueError
        If the mask is empty or not two-dimensional, or ``offset`` is not two integers.
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be two-dimensional; got shape {m.shape}")
    count = _count(count, 3)
    if (
        not isinstance(offset, tuple | list)
        or len(offset) != 2
        or not all(isinstance(v, int | np.integer) and not isinstance(v, bool) for v in offset)
    ):
        raise ValueError(f"offset must be two whole numbers of pixels [x, y]; got {offset!r}")
    outline = max(_outer_contours(m), key=cv2.contourArea).reshape(-1, 2)
    if len(outline) < 3:
        raise ValueError("mask's object is too small for a contour")
    largest = (outline + np.asarray(offset, dtype=np.int32)).astype(np.float64)
    return resample(largest, count, closed=True)


def _outer_contours(mask: NDArray[Any]) -> list[NDArray[np.int32]]:
    """OpenCV's outer contours of the non-zero pixels; ValueError if there are none."""
    pixels = np.asarray(mask)
    # a boolean mask is read as its bytes (0 and 1), not compared and copied
    binary = (
        np.ascontiguousarray(pixels).view(np.uint8)
        if pixels.dtype == np.bool_
        else (pixels > 0).astype(np.uint8)
    )
    found, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if not found:
        raise ValueError("mask has no object pixels")
    return [np.asarray(c, dtype=np.int32) for c in found]


def _pixels(outline: Nodes) -> float:
    """Pixels of a piece from its outline through the boundary pixels' centres: the
    enclosed area plus half the length plus one (Pick's theorem)."""
    return abs(polygon_area(outline)) + perimeter(outline) / 2 + 1


MIN_PIECE_NODES = 16
"""Fewest nodes of a piece of :func:`mask_to_contours`: enough for the chain to hold
a small blob's shape."""
MIN_PIECE_AREA = 100.0
"""Pixels a separate piece of a mask needs to be worth a contour of its own (a 10 x 10
patch): smaller specks are mask noise more often than parts of the object.  The default
of ``efdm track --min-piece-area`` and of the service's masks."""


def mask_to_contours(mask: ArrayLike, count: int, *, min_area: float = 0.0) -> list[Nodes]:
    """Every separate piece of a binary mask as a contour, largest first.

    The largest piece gets ``count`` nodes: its contour is the one
    :func:`mask_to_contour` gives, so a mask in pieces holds its main piece
    exactly as a mask in one piece does.  Every other piece gets nodes at the
    same spacing (``count`` times its perimeter over the largest's), at least
    :data:`MIN_PIECE_NODES` (and at least 3) and at most ``count`` (a thin,
    winding piece is no more detailed than the main one): a piece added never
    takes nodes from another.  (Sharing ``count`` by perimeter cost the main
    piece its detail: ``docs/tracking-log.md``, "A first mask in pieces".)

    Parameters
    ----------
    mask : array_like
        H x W, non-zero = object.
    count : int
        Nodes of the largest piece (>= 3).
    min_area : float
        Pieces of fewer pixels are left out (the largest piece never is);
        :data:`MIN_PIECE_AREA` is the tracking default.

    Raises
    ------
    ValueError
        If the mask is empty or not two-dimensional, or ``count`` < 3.
    """
    m = np.asarray(mask)
    if m.ndim != 2:
        raise ValueError(f"mask must be two-dimensional; got shape {m.shape}")
    count = _count(count, 3)
    found = _outer_contours(m)
    largest = max(range(len(found)), key=lambda i: cv2.contourArea(found[i]))
    if len(found[largest]) < 3:
        raise ValueError("mask's object is too small for a contour")
    outlines = [c.reshape(-1, 2).astype(np.float64) for c in found]
    spacing = max(perimeter(outlines[largest]), 1.0) / count
    floor = max(min(MIN_PIECE_NODES, count), 3)
    pieces = [resample(outlines[largest], count, closed=True)]
    sized = [(_pixels(c), c) for i, c in enumerate(outlines) if i != largest and len(c) >= 3]
    for pixels, outline in sorted(sized, key=lambda piece: -piece[0]):
        if pixels >= min_area:
            share = round(max(perimeter(outline), 1.0) / spacing)
            pieces.append(resample(outline, min(max(floor, share), count), closed=True))
    return pieces


def mask_iou(a: ArrayLike, b: ArrayLike) -> float:
    """Intersection over union of two binary masks (1.0 when both are empty)."""
    ma, mb = np.asarray(a) > 0, np.asarray(b) > 0
    union = np.count_nonzero(ma | mb)
    return 1.0 if union == 0 else np.count_nonzero(ma & mb) / union
