"""What the band cut may change beyond its band: parts taken back, strips crossed, gaps opened.

The band cut (:mod:`engine.tracking.segmentation`) relabels only pixels within
:attr:`TrackerOptions.cut_band` of the chain's contour, so it moves the boundary by at
most the band a frame and cannot run away with the background.  Three things move
faster than that, and each is plain in the cut's p(object) beyond the band:

- a part the contour lost (a dancer's leg swung out, a wing): clearly object-like
  pixels that touch the object are taken back (:func:`regrow`);
- the object's part beyond a thin strip that looks like background (a pole, a bar in
  front of it), inside the object's remembered outline (:func:`bridge`);
- background seen through a gap that opened inside the object (between two limbs):
  clearly background-like pixels connected to the background are left out
  (:func:`carve`).

Each works on the cut's labelling at the cut's resolution (a bool mask of the region,
True on the object), is limited to :data:`REGROW_CAP` of the object a frame, and takes
only pieces at least the disc of :data:`REGROW_OPENING` wide.  Coordinates are
``[x, y]`` pixels (x = column, y = row), as in OpenCV; the masks are indexed
``[row, column]``.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "BRIDGE_GAP",
    "CARVE_BELOW",
    "REGROW_ABOVE",
    "REGROW_CAP",
    "REGROW_OPENING",
    "bridge",
    "carve",
    "regrow",
]

REGROW_ABOVE = 0.9
"""Beyond the band, pixels at least this object-like (colour and motion, as the cut
reads them) that touch the cut's object are taken back (:func:`regrow`)."""
REGROW_OPENING = 2
"""Radius (pixels of the cut's resolution) of the disc the regrown pixels are opened
with: strips of object colour under 5 px wide along the background (a banner's edge, a
shadow's rim) are not taken, a leg or a wing is."""
REGROW_CAP = 0.15
"""Regrowth of more than 15 % of the cut's object in one frame is background of the
object's colours coming in (a leak), not a part the contour lost: none is taken.  The
carving is held to the same share, and so are the object-like pieces the bridge takes
(not the strip it crosses to them, which the remembered outline lays down)."""
CARVE_BELOW = 1 - REGROW_ABOVE
"""Inside the band's fixed object, pixels less object-like than this that reach the
background are a gap that opened (:func:`carve`): as sure of the background as the
regrowth is of the object (on the thirty training sequences, mean J over five node
counts 0.7346 at 0.1 and at 0.2, 0.7313 at 0.05, 0.7283 at 0.3)."""
BRIDGE_GAP = 8
"""Radius (pixels of the cut's resolution) of the disc that joins the object to a clearly
object-like piece beyond a strip (:func:`bridge`): strips up to ``2 * BRIDGE_GAP - 1`` =
15 px wide, a pole or a bar in front of the object, are crossed.  The ``occluder``
condition's sweeping bars are 8-14 px wide, and the pixels their edges blur are not
object-like either: at 7 (strips up to 13 px) ``occluder`` seed 13's bar, 14.3 px from the
object to the part beyond, was never crossed, and the contour shrank with the part below
it (J 0.479).  On the thirty training sequences, 8 with only the pieces held to
:data:`REGROW_CAP` (:func:`bridge`) against 7 with the strip counted too: chosen in four
folds of five from the two runs, mean J over five node counts 0.7494 against 0.7490
(0.7499 at 8 with the strip counted).  On 2026-11-27, 10 crossed no more of the static
bars than 7 (0.7291 against 0.7287, ``docs/tracking-log.md``)."""


_CROSS = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
"""A pixel and its four neighbours."""
_OPENING_DISC = cv2.getStructuringElement(
    cv2.MORPH_ELLIPSE, (2 * REGROW_OPENING + 1, 2 * REGROW_OPENING + 1)
)
"""The disc of radius :data:`REGROW_OPENING` the regrown pixels are opened with."""


def _pieces(
    candidates: NDArray[np.bool_], seg: NDArray[np.bool_]
) -> tuple[NDArray[np.int32], NDArray[np.bool_]] | None:
    """The ``candidates`` opened by the disc of :data:`REGROW_OPENING`, as 4-connected pieces.

    Returns their labels (0: none) and, per label, whether the piece has a 4-neighbour
    in the object ``seg``; None when the opening leaves nothing.
    """
    strong = candidates.astype(np.uint8)
    if not strong.any():
        return None
    strong = np.asarray(cv2.morphologyEx(strong, cv2.MORPH_OPEN, _OPENING_DISC), np.uint8)
    if not strong.any():
        return None
    count, labels = cv2.connectedComponents(strong, connectivity=4)
    near = np.asarray(cv2.dilate(seg.astype(np.uint8), _CROSS), np.uint8) & strong
    touching = np.zeros(count, dtype=np.bool_)
    touching[labels[near > 0]] = True
    return np.asarray(labels, np.int32), touching


def regrow(
    seg: NDArray[np.bool_],
    distance: NDArray[np.float32],
    band: float,
    probability: NDArray[np.float32],
) -> NDArray[np.bool_]:
    """The cut's object with the clearly object-like pixels beyond the band that touch it.

    The cut moves the boundary by at most the band a frame, so a part the contour
    lost (a dancer's leg swung out faster than that, a wing) stays lost while its
    pixels say plainly that they are the object's.  Pixels beyond the band with
    p(object) above :data:`REGROW_ABOVE`, opened by a disc of radius
    :data:`REGROW_OPENING`, are added where they touch the object (4-connected),
    unless they add more than :data:`REGROW_CAP` of it (then none is).  On the thirty
    training sequences, mean J over 15 node counts 0.690 to 0.693, chosen in five
    folds of five over ten of them and in three of five over the other five
    (docs/tracking-log.md, "Parts taken back"); occluded pixels are
    neutral (p = 0.5) and never taken.
    """
    found = _pieces((probability > REGROW_ABOVE) & (distance < -band), seg)
    if found is None:
        return seg
    labels, touching = found
    grown: NDArray[np.bool_] = touching[labels]
    if np.count_nonzero(grown) > REGROW_CAP * np.count_nonzero(seg):
        return seg
    return np.logical_or(seg, grown)


_BRIDGE_DISC = cv2.getStructuringElement(
    cv2.MORPH_ELLIPSE, (2 * BRIDGE_GAP + 1, 2 * BRIDGE_GAP + 1)
)
"""The disc of radius :data:`BRIDGE_GAP` that joins a piece across a strip."""


def bridge(
    seg: NDArray[np.bool_],
    probability: NDArray[np.float32],
    remembered: NDArray[np.bool_],
) -> NDArray[np.bool_]:
    """The cut's object joined, across a thin strip, to the object-like pieces beyond it.

    A thin occluder that looks like background (a pole, a bar of the background's
    colours) sweeping across the object splits it, and the largest piece alone is
    kept: frame after frame the contour stays on the strip's near side and shrinks
    with what is left there, while the far side plainly shows the object's colours.
    Pixels with p(object) above :data:`REGROW_ABOVE` inside the ``remembered``
    outline (bool mask) and outside the object, opened by the disc of
    :data:`REGROW_OPENING`, that do not touch the object but come within
    2 x :data:`BRIDGE_GAP` pixels of it, are added with the strip between (the
    closing of the union by the disc of :data:`BRIDGE_GAP`, inside the outline, near
    those pieces), unless the pieces are more than :data:`REGROW_CAP` of the object
    (then none is).  The strip does not count against that share: a bar across the
    whole object hides more of it than the part that shows beyond it at first, and the
    outline, not the colours, says what the strip covers.  The outline keeps it all to
    where the object was: background of the object's colours beyond a pole is not the
    object's unless its shape says so.
    """
    found = _pieces((probability > REGROW_ABOVE) & remembered & ~seg, seg)
    if found is None:
        return seg
    labels, touching = found
    loose = ~touching  # the pieces that do not touch the object
    loose[0] = False
    if not loose.any():
        return seg
    # what follows reads at most 4 x BRIDGE_GAP px from the loose pieces: their box with
    # that margin gives exactly the whole region's result (borders included)
    ys, xs = np.nonzero(loose[labels])
    margin = 4 * BRIDGE_GAP
    y0, x0 = max(int(ys.min()) - margin, 0), max(int(xs.min()) - margin, 0)
    box = np.s_[y0 : int(ys.max()) + margin + 1, x0 : int(xs.max()) + margin + 1]
    labels_, object_ = labels[box], seg[box].astype(np.uint8)
    reach = np.asarray(cv2.dilate(cv2.dilate(object_, _BRIDGE_DISC), _BRIDGE_DISC)) > 0
    near = np.zeros(len(touching), dtype=np.bool_)
    near[labels_[reach & (labels_ > 0)]] = True
    pieces = (near & loose)[labels_]
    # only the pieces count against the share (not the strip): decided before the strip
    if not pieces.any() or np.count_nonzero(pieces) > REGROW_CAP * np.count_nonzero(seg):
        return seg
    union = (object_ | pieces).astype(np.uint8)
    joined = np.asarray(cv2.morphologyEx(union, cv2.MORPH_CLOSE, _BRIDGE_DISC)) > 0
    around = cv2.dilate(cv2.dilate(pieces.astype(np.uint8), _BRIDGE_DISC), _BRIDGE_DISC)
    inside = remembered[box] & (object_ == 0)
    grown = pieces | (joined & inside & (np.asarray(around) > 0))
    bridged = seg.copy()
    bridged[box] |= grown
    return bridged


def carve(
    seg: NDArray[np.bool_],
    distance: NDArray[np.float32],
    band: float,
    probability: NDArray[np.float32],
) -> NDArray[np.bool_]:
    """The cut's object without the background seen through a gap that opened inside it.

    Two limbs that touched part (a runner's legs, an arm leaving the hip), and the
    background between them lies deeper inside the chain's contour than the band: the
    cut must keep it, and the contour spans the gap frame after frame.  Pixels of the
    object with p(object) below :data:`CARVE_BELOW` are taken out where, 8-connected,
    they reach the cut's background and hold a piece beyond the band at least the disc
    of :data:`REGROW_OPENING` wide (the gap's mouth may be narrower than the disc: it
    is where the contour goes in), unless they are more than :data:`REGROW_CAP` of the
    object (then none is).  A hole that does not reach the background is left: one
    contour cannot leave it out.
    """
    dark = (probability < CARVE_BELOW) & seg
    deep = dark & (distance > band)
    if not deep.any():
        return seg
    deep = np.asarray(cv2.morphologyEx(deep.astype(np.uint8), cv2.MORPH_OPEN, _OPENING_DISC))
    if not deep.any():
        return seg
    count, labels = cv2.connectedComponents(dark.astype(np.uint8), connectivity=8)
    reaching = np.zeros(count, dtype=np.bool_)
    reaching[labels[(np.asarray(cv2.dilate((~seg).astype(np.uint8), _CROSS)) > 0) & dark]] = True
    holding = np.zeros(count, dtype=np.bool_)
    holding[labels[deep > 0]] = True
    gap: NDArray[np.bool_] = (reaching & holding)[labels]
    if not gap.any() or np.count_nonzero(gap) > REGROW_CAP * np.count_nonzero(seg):
        return seg
    return seg & ~gap
