"""The initial contour of ``efdm track``: masks, boxes (snapped), polygons and circles."""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from numpy.typing import NDArray

from efdm_cli._common import EXIT_INVALID, CliError
from engine.geometry import MIN_PIECE_AREA  # re-exported: the CLI's default
from engine.tracking.tracker import MAX_NODES

__all__ = [
    "MIN_PIECE_AREA",
    "initial_contour",
    "initial_contours",
    "initial_objects",
    "parse_box",
    "parse_circle",
    "parse_polygon",
]

Nodes = NDArray[np.float64]
_INIT_OPTIONS = ("--init-mask", "--init-box", "--init-polygon", "--init-circle")


def _numbers(text: str, what: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise CliError(
            f"{what}: {text!r} is not a comma-separated list of numbers", EXIT_INVALID
        ) from None
    if not all(np.isfinite(values)):
        raise CliError(f"{what}: {text!r} has a non-finite number", EXIT_INVALID)
    return values


def parse_polygon(text: str) -> Nodes:
    """``"x,y x,y ..."`` (at least 3 points, enclosing a non-zero area) as an (M, 2) array."""
    what = "--init-polygon"
    points = [_numbers(token, what) for token in text.replace(";", " ").split()]
    if any(len(p) != 2 for p in points):
        raise CliError(f'{what}: expected points "x,y x,y ..."; got {text!r}', EXIT_INVALID)
    if len(points) < 3:
        raise CliError(f"{what}: need at least 3 points; got {len(points)}", EXIT_INVALID)
    poly = np.array(points, dtype=np.float64)
    x, y = poly[:, 0], poly[:, 1]
    if abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) < 1e-9:
        raise CliError(f"{what}: the polygon encloses no area", EXIT_INVALID)
    return poly


def parse_circle(text: str) -> tuple[float, float, float]:
    """``"cx,cy,r"`` with r > 0."""
    values = _numbers(text, "--init-circle")
    if len(values) != 3 or not values[2] > 0:
        raise CliError(f"--init-circle: expected cx,cy,r with r > 0; got {text!r}", EXIT_INVALID)
    return values[0], values[1], values[2]


def parse_box(text: str) -> tuple[float, float, float, float]:
    """``"x0,y0,x1,y1"`` (pixel edges) with x1 > x0 and y1 > y0."""
    values = _numbers(text, "--init-box")
    if len(values) != 4 or not (values[2] > values[0] and values[3] > values[1]):
        raise CliError(
            f"--init-box: expected x0,y0,x1,y1 with x1 > x0 and y1 > y0; got {text!r}",
            EXIT_INVALID,
        )
    return values[0], values[1], values[2], values[3]


def _warn_dropped_pieces(mask: NDArray[np.bool_], what: str, min_area: float) -> None:
    """Say on stderr which separate pieces of the object the track leaves out."""
    import cv2

    count, _, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    areas = sorted((int(a) for a in stats[1:count, cv2.CC_STAT_AREA]), reverse=True)
    dropped = [a for a in areas[1:] if a < min_area]
    if dropped:
        listed = ", ".join(f"{a} px" for a in dropped[:5]) + (", ..." if len(dropped) > 5 else "")
        print(
            f"efdm track: warning: {what} has {len(areas)} separate pieces; "
            f"{len(dropped)} under --min-piece-area {min_area:g} px left out: {listed}",
            file=sys.stderr,
        )


def _read_mask(path: str, label: int | None) -> NDArray[np.bool_]:
    """The object's pixels in a binary mask or label image (:mod:`efdm_cli._masks`)."""
    import cv2

    from efdm_cli._io import read_image
    from efdm_cli._masks import MaskError, object_mask

    image = read_image(path, cv2.IMREAD_UNCHANGED)
    if image.dtype != np.uint8:
        raise CliError(f"mask {path} must be 8-bit (got {image.dtype})", EXIT_INVALID)
    with open(path, "rb") as f:
        head = f.read(16)
    try:
        return object_mask(head, image, f"mask {path}", label)
    except MaskError as exc:
        raise CliError(str(exc), EXIT_INVALID) from None


def initial_objects(
    args: argparse.Namespace,
    size: tuple[int, int],
    first: NDArray[np.uint8] | None = None,
    following: NDArray[np.uint8] | None = None,
) -> dict[int, list[Nodes]]:
    """Each object's initial contours (one per piece), by id.

    Several objects come from several ``--init-box`` (ids 1, 2, ... in their
    order) or from an ``--init-mask`` label image of several labels without
    ``--label`` (ids: the labels); otherwise there is one object, id 1.  ``first`` and
    ``following``: the first two frames (see :func:`initial_contour`).
    """
    frames = (size, first, following)
    boxes: list[str] = list(args.init_box or [])
    if len(boxes) > 1:
        if any(getattr(args, o[2:].replace("-", "_")) is not None for o in _INIT_OPTIONS[2:]):
            raise CliError("--init-box cannot be combined with another --init-*", EXIT_INVALID)
        return {
            k: initial_contours(argparse.Namespace(**{**vars(args), "init_box": box}), *frames)
            for k, box in enumerate(boxes, start=1)
        }
    one = argparse.Namespace(**{**vars(args), "init_box": boxes[0] if boxes else None})
    if args.init_mask is not None and getattr(args, "label", None) is None:
        labels = _labels_in(args.init_mask)
        if len(labels) > 1:
            return {
                k: initial_contours(argparse.Namespace(**{**vars(one), "label": k}), *frames)
                for k in labels
            }
    return {1: initial_contours(one, *frames)}


def _labels_in(path: str) -> list[int]:
    """The non-zero labels of a mask file (a binary mask has one)."""
    import cv2

    from efdm_cli._io import read_image
    from efdm_cli._masks import MaskError, labels_of

    image = read_image(path, cv2.IMREAD_UNCHANGED)
    try:
        labels = labels_of(image, f"mask {path}")
    except MaskError:
        return []  # the single-object path says what is wrong with it
    return [int(v) for v in np.unique(labels) if v != 0]


def initial_contours(
    args: argparse.Namespace,
    size: tuple[int, int],
    first: NDArray[np.uint8] | None = None,
    following: NDArray[np.uint8] | None = None,
) -> list[Nodes]:
    """The initial contour of each piece of the object: several only for a mask, or a
    snapped outline, in separate pieces of at least ``--min-piece-area`` pixels (see
    :func:`initial_contour`; the largest piece has ``--nodes`` nodes, the others the same
    spacing, :func:`engine.geometry.mask_to_contours`)."""
    from engine.geometry import mask_to_contours

    nodes, mask = _initial(args, size, first, following)
    if mask is None and args.init_mask is not None:
        mask = _read_mask(args.init_mask, getattr(args, "label", None))  # read before: valid
    if mask is None:
        return [nodes]
    area = getattr(args, "min_piece_area", None)
    pieces = mask_to_contours(mask, args.nodes, min_area=MIN_PIECE_AREA if area is None else area)
    return pieces if len(pieces) > 1 else [nodes]


def initial_contour(
    args: argparse.Namespace,
    size: tuple[int, int],
    first: NDArray[np.uint8] | None = None,
    following: NDArray[np.uint8] | None = None,
) -> Nodes:
    """The ``--nodes`` initial nodes from exactly one ``--init-*`` option (of the largest
    piece, for an object in pieces: :func:`initial_contours` gives them all).

    A box (``--init-box``, unless ``--no-snap``) or a polygon or circle with
    ``--snap`` is snapped onto the object inside it in the ``first`` frame
    (:func:`engine.tracking.snap.snap`), with what moved between it and the
    ``following`` one.

    Parameters
    ----------
    args : argparse.Namespace
        Parsed ``efdm track`` arguments.
    size : tuple of int
        ``(width, height)`` of the first frame.
    first : numpy.ndarray, optional
        The first frame (needed to snap).
    following : numpy.ndarray, optional
        The second frame, of the same size (the snap's motion cue).

    Raises
    ------
    CliError
        Invalid options, an unreadable or empty mask, or a contour entirely
        outside the frame.
    """
    return _initial(args, size, first, following)[0]


def _initial(
    args: argparse.Namespace,
    size: tuple[int, int],
    first: NDArray[np.uint8] | None,
    following: NDArray[np.uint8] | None,
) -> tuple[Nodes, NDArray[np.bool_] | None]:
    """:func:`initial_contour`'s nodes, and the snapped mask when the outline was snapped."""
    from engine.geometry import (
        box_outline,
        circle_nodes,
        contour_to_mask,
        mask_to_contour,
        resample,
    )

    given = [o for o in _INIT_OPTIONS if getattr(args, o[2:].replace("-", "_")) is not None]
    if len(given) != 1:
        got = "none" if not given else " and ".join(given)
        raise CliError(f"give exactly one of {', '.join(_INIT_OPTIONS)} (got {got})", EXIT_INVALID)
    if not 3 <= args.nodes <= MAX_NODES:
        raise CliError(f"--nodes must be in [3, {MAX_NODES}]; got {args.nodes}", EXIT_INVALID)
    if getattr(args, "label", None) is not None and args.init_mask is None:
        raise CliError("--label chooses an object of --init-mask: give --init-mask", EXIT_INVALID)
    width, height = size
    snapping = getattr(args, "snap", None)
    box = getattr(args, "init_box", None)
    if snapping is None:
        snapping = box is not None  # boxes snap by default, outlines only when asked
    area = getattr(args, "min_piece_area", None)
    if area is not None and not (math.isfinite(area) and area >= 0):
        raise CliError(
            f"--min-piece-area must be a number of pixels >= 0; got {area:g}", EXIT_INVALID
        )
    if area is not None and args.init_mask is None and not snapping:
        raise CliError(
            "--min-piece-area splits a mask or a snapped outline into pieces: give --init-mask, "
            "or snap the outline (--snap)",
            EXIT_INVALID,
        )
    if args.init_circle is not None:
        cx, cy, r = parse_circle(args.init_circle)
        nodes = circle_nodes([cx, cy], r, args.nodes)
    elif box is not None:
        nodes = box_outline(parse_box(box), args.nodes)
    elif args.init_polygon is not None:
        nodes = resample(parse_polygon(args.init_polygon), args.nodes, closed=True)
    else:
        snapping = False
        mask = _read_mask(args.init_mask, getattr(args, "label", None))
        if mask.shape != (height, width):
            raise CliError(
                f"mask {args.init_mask} is {mask.shape[1]} x {mask.shape[0]}, "
                f"the frames are {width} x {height}",
                EXIT_INVALID,
            )
        try:
            nodes = mask_to_contour(mask, args.nodes)
        except ValueError as exc:
            raise CliError(f"mask {args.init_mask}: {exc}", EXIT_INVALID) from None
        area = getattr(args, "min_piece_area", None)
        _warn_dropped_pieces(
            mask, f"mask {args.init_mask}", MIN_PIECE_AREA if area is None else area
        )
    x, y = nodes[:, 0], nodes[:, 1]
    inside = (x >= -0.5) & (x <= width - 0.5) & (y >= -0.5) & (y <= height - 0.5)
    if not inside.any() and not contour_to_mask(nodes, (height, width)).any():
        raise CliError(f"initial contour lies outside the frame ({width} x {height})", EXIT_INVALID)
    if snapping and first is not None:
        from engine.tracking.snap import snap

        outline = parse_box(box) if box is not None else nodes
        try:
            snapped = np.asarray(snap(first, outline, next_frame=following), dtype=bool)
            return mask_to_contour(snapped, args.nodes), snapped
        except ValueError as exc:
            raise CliError(f"snap: {exc}", EXIT_INVALID) from None
    return nodes, None
