"""Snap a rough outline onto the object inside it: a box or a loose polygon becomes a mask.

Nobody should have to trace a boundary to start a track.  Given a box (or a
loose polygon, such as a dragged circle) around the object on the first
frame, :func:`snap` labels the object's pixels with OpenCV's GrabCut
(iterated graph cuts with colour mixture models, Rother et al. 2004), using
what the outline says:

- everything outside the outline is background (definite labels), and a
  margin around it teaches the background's colours;
- the solve runs on the region around the outline shrunk to at most
  :data:`SIDE` pixels (an 854 x 480 frame's snap takes tenths of a second,
  where GrabCut on the whole frame takes seconds), and the labels are
  brought back to full resolution smoothly;
- a box is taken as tight, the bounding box of the object (as the API and
  ``--init-box`` define it), so the object reaches each of its rows and
  columns: where the cut left a row or column of the box empty, the pixel
  on it that the colour models find most object-like is pinned as object
  (when it looks more like the object than the background) and GrabCut
  resumes (the tightness prior of Lempitsky et al., "Image segmentation with
  a bounding box prior", ICCV 2009, by their pinpointing).  It brings back
  the thin ends GrabCut drops: a hockey stick, a boat's bow, a foot;
- when the colour models find no object (a box mostly of background
  colours), the solve is repeated with the outline's central part as
  definite object, and if that fails too the outline's inscribed ellipse is
  given: a contour to start from, never nothing;
- given the next frame, what moved otherwise than the background is likelier
  object: the object's motion is measured on the colour cut's contour, the
  background's around it, and the motion contrast
  (:mod:`engine.tracking.motion_contrast`) of each pixel is added to the colour
  models' log-odds in one more cut of GrabCut's energy
  (:func:`engine.tracking._grabcut.cut_with_odds`).  A fence, a wall or a wake
  of the object's colours inside the box goes; on the thirty DAVIS training
  sequences the first-frame IoU goes from 0.756 to 0.802 (the weight of the
  motion cross-validated: 0.794 held out).

Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV; a box is
``(x0, y0, x1, y1)`` in pixel edges: the box of a mask whose pixels span
columns ``x0 .. x1 - 1`` and rows ``y0 .. y1 - 1``.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from engine.geometry import as_nodes, contour_to_mask, mask_to_contour
from engine.tracking._frames import as_frame, repeatable_opencv
from engine.tracking._grabcut import GrabCut, cut_with_odds, grabcut
from engine.tracking.background import background_motion
from engine.tracking.motion import estimate_motion
from engine.tracking.motion_contrast import motion_ratio

__all__ = ["SIDE", "snap"]

SIDE = 256
"""Longest side (pixels) of the region the cut is solved on.  On the thirty DAVIS
training sequences (each first mask's box), with the tightness prior: 256, 272,
288 and 320 gave a mean IoU of 0.753-0.756 (304: 0.744, the spread of such
choices), the slowest snap taking 0.56 s at 256 and 1.06 s at 320 (two processes
running).  Without the prior, 240 gave 0.72 and 320 0.74, and a second, finer
pass at 480 added nothing."""
MARGIN = 0.15
"""Background margin around the outline, as a share of its larger side (plus
:data:`MARGIN_PIXELS`): enough background for GrabCut's colour model."""
MARGIN_PIXELS = 8
"""Pixels added to the margin, for small outlines."""
ITERATIONS = 3
"""GrabCut iterations: 3 to 10 gave the same mean IoU on the training sequences
(0.736-0.740); 3, the cheapest of that plateau, keeps the slowest snap of the thirty
at 0.77 s (5 took 1.05 s, over the one-second goal, with two processes running)."""
TIGHT_ITERATIONS = 2
"""GrabCut iterations resumed after pinning the box's empty rows and columns: on the
thirty training sequences 2 scored 0.005-0.01 above 1 at every :data:`SIDE` tried
(256-320), 3 no more than 2."""
STRAY_SHARE = 0.01
"""A piece that only pinning made (no pixel of it in the cut before) and smaller
than 1 % of the object is a pin that found nothing to join: dropped."""
MIN_SHARE = 0.05
"""A cut keeping less than 5 % of the outline's area found no object: retried with
the central part as definite object."""
CORE = 0.25
"""Half-axes of that central part, as a share of the outline box's sides."""
MOTION_WEIGHT = 10.0
"""Weight of the motion contrast's log-odds (at most +-2 each,
:data:`~engine.tracking.motion_contrast.GAIN`) against the colour models' in the cut
with the next frame: at most +-20, enough to overrule colour where the motion is
clear.  Chosen by five-fold cross-validation on the thirty DAVIS training sequences
(weights 3, 6, 10 and 15 with one following frame; 10 in four folds of five):
first-frame IoU 0.794 held out, against 0.756 from the first frame alone; on all
thirty 6 to 10 scored 0.796-0.799, 3 0.783 and 15 0.796, and two or three following
frames no better (0.778-0.798).  Leaving neutral the background the object is about to
cover (:func:`_motion_odds`) then took the thirty to 0.802 and the extra pixels within
4 px outside the object from 8.6 % to 7.9 % of its area (7.6 % from colour alone)."""
MOTION_NODES = 128
"""Nodes of the colour cut's contour that the object's motion is measured on (as the
tracker's default contour)."""
DRAWN_UP_TO = 2**26
"""Largest centre coordinate or semi-axis (pixels) of an ellipse OpenCV draws: with its 4
fractional bits, 16 times this stays well inside the int32 it takes.  A larger one (a box
of 10^9 px around the frame) is filled from its equation instead."""


def _box_of(
    outline: Sequence[float] | ArrayLike,
) -> tuple[tuple[float, ...], NDArray[np.float64] | None]:
    """The outline's box (pixel edges) and its polygon (None for a box); ValueError if malformed."""
    arr = np.asarray(outline, dtype=np.float64)
    if arr.shape == (4,):
        if not np.isfinite(arr).all():
            raise ValueError(f"box must be finite numbers; got {arr.tolist()}")
        x0, y0, x1, y1 = (float(v) for v in arr)
        if not (x1 > x0 and y1 > y0):
            raise ValueError(
                f"box must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0; got {arr.tolist()}"
            )
        return (x0, y0, x1, y1), None
    polygon = as_nodes(arr)  # ValueError unless (M, 2), M >= 3, finite
    lo, hi = polygon.min(axis=0), polygon.max(axis=0)
    # the box of the pixels whose centres the polygon covers: centres at integers
    return (float(lo[0]), float(lo[1]), float(hi[0]) + 1.0, float(hi[1]) + 1.0), polygon


def snap(
    image: NDArray[np.uint8],
    outline: Sequence[float] | ArrayLike,
    *,
    next_frame: NDArray[np.uint8] | None = None,
) -> NDArray[np.uint8]:
    """The object inside a rough outline, as a mask.

    Parameters
    ----------
    image : numpy.ndarray
        H x W x 3 BGR (or H x W grey) uint8 frame.
    outline : array_like
        A box ``[x0, y0, x1, y1]`` (pixel edges, see the module notes) or a
        closed polygon, (M, 2) ``[x, y]`` pixels, M >= 3, around the object.
    next_frame : numpy.ndarray, optional
        The frame after ``image`` (same size, BGR or grey uint8): what moved
        otherwise than the background between the two is likelier object
        (see the module notes).  Without it, colour alone decides.

    Returns
    -------
    numpy.ndarray
        H x W uint8 mask, 255 on the object, 0 elsewhere; never empty for an
        outline that overlaps the frame.

    Raises
    ------
    ValueError
        If the image is not a non-empty uint8 image, the box is empty,
        inverted or not finite, the polygon is malformed, the outline
        lies entirely outside the frame, or ``next_frame`` is not a uint8
        image of the same size.
    """
    frame = np.asarray(image)
    if frame.dtype != np.uint8 or frame.ndim not in (2, 3) or min(frame.shape[:2]) < 1:
        raise ValueError("image must be a non-empty H x W (x 3) uint8 array")
    if frame.ndim == 2 or frame.shape[2] == 1:
        frame = np.asarray(cv2.cvtColor(frame.reshape(frame.shape[:2]), cv2.COLOR_GRAY2BGR))
    elif frame.shape[2] != 3:
        raise ValueError(f"image must have 1 or 3 channels; got {frame.shape[2]}")
    height, width = frame.shape[:2]
    following = None if next_frame is None else _following(next_frame, (height, width))
    (x0, y0, x1, y1), polygon = _box_of(outline)
    inside = _outline_mask((height, width), (x0, y0, x1, y1), polygon)
    if not inside.any():
        raise ValueError(f"the outline lies outside the frame ({width} x {height})")
    margin = round(MARGIN * max(x1 - x0, y1 - y0)) + MARGIN_PIXELS
    rx0, ry0 = max(int(np.floor(x0)) - margin, 0), max(int(np.floor(y0)) - margin, 0)
    rx1, ry1 = min(int(np.ceil(x1)) + margin, width), min(int(np.ceil(y1)) + margin, height)
    region, allowed = frame[ry0:ry1, rx0:rx1], inside[ry0:ry1, rx0:rx1]
    h, w = allowed.shape
    scale = min(1.0, SIDE / max(h, w))
    size = (max(round(w * scale), 1), max(round(h * scale), 1))
    small = np.asarray(cv2.resize(region, size, interpolation=cv2.INTER_AREA), np.uint8)
    wanted = np.asarray(cv2.resize(allowed, size, interpolation=cv2.INTER_NEAREST), np.uint8)
    cut = _cut(small, wanted, tight=polygon is None)
    if cut is None:
        mask = _ellipse(inside.shape, (x0, y0, x1, y1)) & inside
    else:
        found, models = cut
        box = (rx0, ry0, rx1, ry1)
        mask = _full(found, allowed, box, (height, width))
        if following is not None and mask.any():
            odds = _motion_odds(frame, following, mask, box)
            if odds is not None:
                extra = cv2.resize(odds, size, interpolation=cv2.INTER_AREA).astype(np.float64)
                found = cut_with_odds(small, models, MOTION_WEIGHT * extra)
                mask = _full(found, allowed, box, (height, width))
    if not mask.any():
        mask = inside
    return np.asarray(mask, np.uint8) * np.uint8(255)


def _following(image: NDArray[np.uint8], shape: tuple[int, int]) -> NDArray[np.uint8]:
    """The next frame, grey; ValueError unless a uint8 image of ``shape`` (height, width)."""
    frame = np.asarray(image)
    if frame.dtype != np.uint8 or frame.shape[:2] != shape:
        raise ValueError(
            f"next_frame must be a uint8 image of the frame's size {shape[1]} x {shape[0]}; "
            f"got {frame.dtype} {frame.shape}"
        )
    return as_frame(frame)[1]


def _full(
    found: NDArray[np.uint8],
    allowed: NDArray[np.uint8],
    region: tuple[int, int, int, int],
    shape: tuple[int, int],
) -> NDArray[np.uint8]:
    """The shrunk region's labels back at full resolution, smooth rather than blocky.

    ``region`` (x0, y0, x1, y1) of a frame of ``shape`` (height, width); ``allowed``:
    1 on the region's pixels inside the outline, the only ones kept.
    """
    x0, y0, x1, y1 = region
    soft = cv2.resize(found.astype(np.float32), (x1 - x0, y1 - y0), interpolation=cv2.INTER_LINEAR)
    mask = np.zeros(shape, np.uint8)
    mask[y0:y1, x0:x1] = (soft >= 0.5) & (allowed > 0)
    return mask


def _outline_mask(
    shape: tuple[int, int], box: tuple[float, ...], polygon: NDArray[np.float64] | None
) -> NDArray[np.uint8]:
    """1 on the frame's pixels inside the outline (box: pixel edges; polygon: centres)."""
    if polygon is not None:
        return np.asarray(contour_to_mask(polygon, shape) > 0, np.uint8)
    height, width = shape
    x0, y0, x1, y1 = box
    mask = np.zeros(shape, np.uint8)
    cx0, cy0 = max(int(np.ceil(x0 - 0.5)), 0), max(int(np.ceil(y0 - 0.5)), 0)
    cx1, cy1 = min(int(np.ceil(x1 - 0.5)), width), min(int(np.ceil(y1 - 0.5)), height)
    mask[cy0:cy1, cx0:cx1] = 1
    return mask


def _ellipse(shape: tuple[int, int], box: tuple[float, ...]) -> NDArray[np.uint8]:
    """1 inside the ellipse inscribed in the box."""
    x0, y0, x1, y1 = box
    centre = ((x0 + x1) / 2 - 0.5, (y0 + y1) / 2 - 0.5)
    axes = (max((x1 - x0) / 2, 0.5), max((y1 - y0) / 2, 0.5))
    if max(abs(centre[0]), abs(centre[1]), *axes) > DRAWN_UP_TO:
        ys, xs = np.ogrid[: shape[0], : shape[1]]
        dx, dy = (xs - centre[0]) / axes[0], (ys - centre[1]) / axes[1]
        return np.asarray(dx * dx + dy * dy <= 1.0, np.uint8)
    mask = np.zeros(shape, np.uint8)
    shift = 4  # sub-pixel centre and axes
    cv2.ellipse(
        mask,
        (round(centre[0] * 16), round(centre[1] * 16)),
        (round(axes[0] * 16), round(axes[1] * 16)),
        0.0, 0.0, 360.0, 1, -1, cv2.LINE_8, shift,
    )  # fmt: skip
    return mask


def _cut(
    image: NDArray[np.uint8], wanted: NDArray[np.uint8], *, tight: bool
) -> tuple[NDArray[np.uint8], GrabCut] | None:
    """GrabCut of ``image`` with ``wanted`` as the possible object: the object found and
    the cut it came from (its models and definite labels); None if it finds none.

    ``tight``: ``wanted`` is a box the object reaches on every row and column
    (:func:`_tighten`).
    """
    area = int(np.count_nonzero(wanted))
    if area < 4 or min(image.shape[:2]) < 2:
        return None
    start = np.where(wanted > 0, cv2.GC_PR_FGD, cv2.GC_BGD).astype(np.uint8)
    cut = grabcut(image, start, ITERATIONS)
    if cut is None or np.count_nonzero(cut.found) < MIN_SHARE * area:
        ys, xs = np.nonzero(wanted)
        box = (float(xs.min()), float(ys.min()), float(xs.max()) + 1, float(ys.max()) + 1)
        core = _ellipse(wanted.shape, _shrunk(box, 2 * CORE)) & wanted
        seeded = start.copy()
        seeded[core > 0] = cv2.GC_FGD
        cut = grabcut(image, seeded, ITERATIONS)
    if cut is None or np.count_nonzero(cut.found) < MIN_SHARE * area:
        return None
    return _tighten(image, wanted, cut) if tight else (cut.found, cut)


def _shrunk(box: tuple[float, ...], share: float) -> tuple[float, ...]:
    """The box scaled by ``share`` about its centre."""
    x0, y0, x1, y1 = box
    cx, cy, hw, hh = (x0 + x1) / 2, (y0 + y1) / 2, share * (x1 - x0) / 2, share * (y1 - y0) / 2
    return (cx - hw, cy - hh, cx + hw, cy + hh)


def _tighten(
    image: NDArray[np.uint8], box: NDArray[np.uint8], cut: GrabCut
) -> tuple[NDArray[np.uint8], GrabCut]:
    """The cut with the box's tightness prior: every row and column of the box meets the object.

    One round of Lempitsky et al.'s pinpointing (ICCV 2009): on each row and column
    of ``box`` (1 on the box's pixels) without object, the pixel whose colour is
    likelier under the object's model than the background's, by the largest
    margin, becomes definite object, and GrabCut resumes for
    :data:`TIGHT_ITERATIONS`.  A line with no such pixel is left empty (a box
    drawn loose on that side).  Returns the object found and the cut it came from.
    """
    found = cut.found
    rows, cols = np.flatnonzero(box.any(axis=1)), np.flatnonzero(box.any(axis=0))
    empty_rows, empty_cols = rows[~found[rows].any(axis=1)], cols[~found[:, cols].any(axis=0)]
    if not len(empty_rows) and not len(empty_cols):
        return found, cut
    lines = np.zeros(box.shape, np.bool_)
    lines[empty_rows, :] = True
    lines[:, empty_cols] = True
    lines &= box > 0
    odds = np.full(box.shape, -np.inf)
    odds[lines] = cut.odds(image[lines].reshape(-1, 1, 3)).ravel()
    labels = cut.labels.copy()
    on_rows = np.argmax(odds[empty_rows], axis=1)
    on_cols = np.argmax(odds[:, empty_cols], axis=0)
    pins_y = np.concatenate([empty_rows, on_cols])
    pins_x = np.concatenate([on_rows, empty_cols])
    likelier = odds[pins_y, pins_x] > 0
    labels[pins_y[likelier], pins_x[likelier]] = cv2.GC_FGD
    pinned = bool(likelier.any())
    if not pinned:
        return found, cut
    resumed = grabcut(image, labels, TIGHT_ITERATIONS, resume=cut)
    if resumed is None:
        return found, cut
    return _without_strays(resumed.found, found), resumed


def _without_strays(found: NDArray[np.uint8], before: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``found`` less its pieces that are new since ``before`` and under :data:`STRAY_SHARE`."""
    count, labels = cv2.connectedComponents(found, connectivity=8)
    sizes = np.bincount(labels.ravel(), minlength=count)
    old = np.bincount(labels.ravel(), weights=before.ravel(), minlength=count) > 0
    keep = old | (sizes >= STRAY_SHARE * sizes[1:].sum())
    keep[0] = False
    return np.asarray(keep[labels], np.uint8)


def _motion_odds(
    frame: NDArray[np.uint8],
    following: NDArray[np.uint8],
    mask: NDArray[np.uint8],
    region: tuple[int, int, int, int],
) -> NDArray[np.float32] | None:
    """Log-odds that each pixel of ``region`` moves with the object found, not the background.

    The object's similarity from ``frame`` to ``following`` (grey) is measured on the
    contour of ``mask`` (:func:`~engine.tracking.motion.estimate_motion`), the
    background's around where that contour moves to
    (:func:`~engine.tracking.background.background_motion`), and the motion contrast
    (:func:`~engine.tracking.motion_contrast.motion_ratio`) compares each pixel of
    ``frame`` with ``following`` warped back by either.  The background the object is
    about to cover is matched by neither motion and reads as moving with the object (a
    rim along the leading edge, all round an approaching object): it is left neutral.
    None when the object's or the background's motion cannot be measured, or they are alike.
    """
    x0, y0, x1, y1 = region
    shape = (y1 - y0, x1 - x0)
    grey = as_frame(frame)[1]
    nodes = mask_to_contour(mask, MOTION_NODES)
    with repeatable_opencv():
        motion = estimate_motion(grey, following, nodes, figure_ground=True)
        if motion.inlier_ratio <= 0:
            return None
        moved = motion.apply(nodes)
        before = np.ascontiguousarray(following[y0:y1, x0:x1])
        after = np.ascontiguousarray(grey[y0:y1, x0:x1])
        background = background_motion(before, after, moved, (x0, y0))
        if background is None:
            return None
        back = np.asarray(cv2.invertAffineTransform(motion.matrix), np.float64)
        ratio = motion_ratio(following, grey, (x0, y0), shape, moved, back, background)
    if ratio is None:
        return None
    odds = np.log(ratio)
    # where the object will be, in this frame's background: what it is about to cover
    ahead = moved @ background[:, :2].T + background[:, 2] - [x0, y0]
    odds[(contour_to_mask(ahead, shape) > 0) & (mask[y0:y1, x0:x1] == 0)] = 0.0
    return odds
