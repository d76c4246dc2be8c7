"""Occluders: pixels that were the object's and now look like background.

A pixel inside the object's rigidly moved silhouette whose object-attached
place in the previous frame was object-like, but which now looks like
background, is most likely covered by something passing in front: it
should neither pull the contour in nor count as the object's edge, and the
object goes on under it.  Coordinates are ``[x, y]`` pixels.

The rule cannot tell an occluder from background that the object's own motion
uncovered (a limb moved away inside the body's rigidly moved outline): both
were the object's and look like background now.  Their colours can, often: what
a limb uncovers is the background around the object, while a pole or a bar in
front usually has colours that ring shows little of.  Such a *foreign* piece
sets :attr:`~engine.tracking.maps.Maps.in_front`: the object is partly behind
something, and its dense flow next to it is the front object's.  A piece whose
colours *are* the ring's is background the object uncovered (a gap opening
between limbs): it is not covered at all, and its colours count as they are
(:func:`piece_overlaps`, :data:`REVEALED_FROM`).  Made neutral, it would stay
the object's, and the contour would bridge the gap for as long as it lasts.
"""

from __future__ import annotations

from typing import TypeAlias

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import contour_to_mask
from engine.tracking.maps import Maps

__all__ = ["LocatedProbability", "Silhouette", "foreign", "piece_overlaps", "unoccluded"]

LocatedProbability: TypeAlias = tuple[tuple[int, int], NDArray[np.uint8]]
"""p(object) as 0-255 over a region of a frame, with the region's ``(x, y)`` origin."""

Silhouette: TypeAlias = tuple[NDArray[np.float64], NDArray[np.float64]]
"""The object's 2 x 3 similarity motion and the previous contour moved by it, ``[x, y]``."""

BACKGROUND_BELOW = 0.35
"""A pixel looks like background now when p(object) < 0.35: clearly below the
0.5 of an unknown colour, so a merely ambiguous pixel is not taken for an occluder."""
OBJECT_ABOVE = 166
"""A pixel was the object's when its previous p(object) rounds above 166/255
(0.65): the mirror image of :data:`BACKGROUND_BELOW` around 0.5."""
RIM_SLACK = 3
"""Pixels of slack around the silhouette: the rigid motion misses the object's
own deformation by about that much between frames."""
NEUTRAL = 0.5
"""p(object) of a covered pixel during refinement: no pull either way."""
FOREIGN_BELOW = 0.25
"""A covered piece is foreign when its colour histogram and the ring's intersect
below 0.25.  Measured on the synthetic conditions: a bar in front scores 0-0.16,
the background uncovered between an articulated figure's limbs a median of 0.75
(0.39 at its 10th percentile)."""
REVEALED_FROM = 0.4
"""A covered piece is background the object uncovered when its colour histogram and
the ring's intersect at 0.4 or more: about the 10th percentile of the gaps between an
articulated figure's limbs (0.39), well clear of a bar in front (0-0.16).  Pieces in
between stay covered, as the rule found them.  Cross-validated on the thirty training
sequences over 0.25, 0.33, 0.4, 0.45, 0.5 and 0.65 (five node counts): 0.4 was chosen
in four folds of five (docs/tracking-log.md, "Background the object uncovered")."""
RING = 8
"""Width in pixels of the ring outside the moved contour whose colours stand for
the object's surroundings (the colour model's own ring is wider: this one is what
lies right next to the object, where an uncovered gap's colours come from)."""
MIN_PIECE = 20
"""Fewest pixels of a covered piece judged by its colours: a smaller one is a
few stray pixels, whose histogram says nothing."""
RING_STEP = 2
"""The ring's histogram takes every second pixel of every second row: a quarter of
the work, and still a thousand pixels or more round any object the rule judges."""
COLOUR_BITS = 3
"""Colours are compared at 3 bits a channel (512 bins in colour): coarse enough
that a few hundred pixels fill a histogram."""


def unoccluded(
    maps: Maps,
    previous: LocatedProbability | None,
    silhouette: Silhouette,
    image: NDArray[np.uint8] | None = None,
    *,
    front: bool = True,
    reveal: bool = True,
) -> tuple[Maps, Maps]:
    """Colour evidence with occluders made neutral (p = 0.5).

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
    image : numpy.ndarray, optional
        The frame the maps were made from (H x W x 3 BGR or H x W uint8):
        given it, the covered pieces are judged by their colours
        (:func:`piece_overlaps`); without it, every covered pixel stays so.
    front : bool, default True
        Given ``image``: set the first map's ``in_front`` when a piece is
        foreign (:func:`foreign`).
    reveal : bool, default True
        Given ``image``: a piece whose colours are the surroundings' (from
        :data:`REVEALED_FROM`) is background the object uncovered, not covered.

    Returns
    -------
    refine : Maps
        ``maps`` with the covered pixels at p = 0.5, for the refinement
        (``observed`` keeps what the pixels look like).
    remember : Maps
        ``maps`` with the covered pixels at their previous p(object) (the
        object goes on under the occluder), for the next frame.
        Both are ``maps`` itself when no pixel is covered (or every covered
        piece is background the object uncovered).
    """
    from engine.tracking._image_kernels import occluded

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
    near = np.ones((2 * RIM_SLACK + 1, 2 * RIM_SLACK + 1), np.uint8)
    silhouette_mask = contour_to_mask(rest - [ox, oy], (h, w))
    inside = np.asarray(cv2.dilate(silhouette_mask, near), np.uint8)
    where, was = occluded(
        np.ascontiguousarray(maps.probability, dtype=np.float32),
        inside,
        np.ascontiguousarray(was_prob, dtype=np.uint8),
        m,
        BACKGROUND_BELOW,
        OBJECT_ABOVE,
    )
    in_front = False
    if image is not None and (front or reveal) and len(where) >= MIN_PIECE:
        covered = np.zeros((h, w), np.bool_)
        covered.reshape(-1)[where] = True
        labels, overlaps = piece_overlaps(
            image, (ox, oy), covered, silhouette_mask.astype(np.bool_)
        )
        in_front = front and bool(np.any(overlaps < FOREIGN_BELOW))
        if reveal and np.any(overlaps >= REVEALED_FROM):
            seen = np.concatenate([[False], overlaps >= REVEALED_FROM])
            kept = ~seen[labels.reshape(-1)[where]]
            where, was = where[kept], was[kept]
    if len(where) == 0:
        return maps, maps
    prob = maps.probability.copy()
    prob.reshape(-1)[where] = NEUTRAL  # a view of the copy: faster than .flat
    memory = maps.probability.copy()
    memory.reshape(-1)[where] = was
    return (
        Maps(
            maps.origin,
            prob,
            maps.edges,
            maps.edge_step,
            observed=maps.probability,
            in_front=in_front,
        ),
        Maps(maps.origin, memory, maps.edges, maps.edge_step),
    )


def foreign(
    image: NDArray[np.uint8],
    origin: tuple[int, int],
    covered: NDArray[np.bool_],
    silhouette: NDArray[np.bool_],
) -> bool:
    """Whether a covered piece has colours the object's surroundings lack.

    Parameters are those of :func:`piece_overlaps`.

    Returns
    -------
    bool
        True when a piece's colours meet the ring's below :data:`FOREIGN_BELOW`;
        False when no piece is foreign or none is judged.

    Raises
    ------
    ValueError
        As :func:`piece_overlaps`.
    """
    _, overlaps = piece_overlaps(image, origin, covered, silhouette)
    return bool(np.any(overlaps < FOREIGN_BELOW))


def piece_overlaps(
    image: NDArray[np.uint8],
    origin: tuple[int, int],
    covered: NDArray[np.bool_],
    silhouette: NDArray[np.bool_],
) -> tuple[NDArray[np.int32], NDArray[np.float64]]:
    """How much each covered piece's colours are those of the object's surroundings.

    Parameters
    ----------
    image : numpy.ndarray
        uint8 H x W x 3 (BGR) or H x W frame.
    origin : tuple of int
        ``(x, y)`` of the region that ``covered`` and ``silhouette`` cover.
    covered : numpy.ndarray
        h x w bool: the region's pixels the occlusion rule took for covered.
    silhouette : numpy.ndarray
        h x w bool: the object's rigidly moved silhouette in the region.

    Returns
    -------
    labels : numpy.ndarray
        h x w int32: 0, or the number (from 1) of the judged piece a pixel is in:
        an 8-connected piece of ``covered`` of at least :data:`MIN_PIECE` pixels.
    overlaps : numpy.ndarray
        Per judged piece, in label order, the intersection of its colour histogram
        (3 bits a channel) with that of the ring :data:`RING` pixels wide outside
        ``silhouette`` (covered pixels left out, sampled on every
        :data:`RING_STEP`-th pixel of every :data:`RING_STEP`-th row): 0 for
        colours the ring never shows, 1 for the ring's own.  Empty when no piece
        is large enough or the ring is empty.

    Raises
    ------
    ValueError
        If ``covered`` and ``silhouette`` differ in shape or the region is not
        inside ``image``.
    """
    from engine.tracking._occluder_kernels import label_histograms, ring_histogram

    x, y = (int(v) for v in origin)
    h, w = covered.shape
    outside = x < 0 or y < 0 or x + w > image.shape[1] or y + h > image.shape[0]
    if silhouette.shape != covered.shape or outside:
        raise ValueError(
            f"covered {covered.shape} and silhouette {silhouette.shape} must be one region "
            f"inside the image {image.shape[:2]}; the region's origin is {(x, y)}"
        )
    labels = np.zeros((h, w), np.int32)
    none = np.zeros(0, np.float64)
    if np.count_nonzero(covered) < MIN_PIECE:
        return labels, none
    pixels = np.ascontiguousarray(image if image.ndim == 3 else image[:, :, None])
    # the pieces, at full resolution within the covered pixels' box
    left, top, width, height = cv2.boundingRect(np.ascontiguousarray(covered).view(np.uint8))
    right, bottom = left + width, top + height
    count, found = cv2.connectedComponents(
        covered[top:bottom, left:right].astype(np.uint8), connectivity=8
    )
    box = np.asarray(found, np.int32)
    at = (x + left, y + top)
    counts, sizes, judged = label_histograms(pixels, at, box, count, MIN_PIECE, COLOUR_BITS)
    if len(sizes) == 0:
        return labels, none
    # the ring, sampled
    step = RING_STEP
    inside = np.ascontiguousarray(silhouette[::step, ::step], np.uint8)
    reach = 2 * (RING // step) + 1
    wide = np.asarray(cv2.dilate(inside, np.ones((reach, reach), np.uint8)), np.uint8)
    left_out = np.ascontiguousarray(covered[::step, ::step], np.uint8)
    ring = ring_histogram(pixels, (x, y), step, wide, inside, left_out, COLOUR_BITS)
    if ring.sum() == 0:
        return labels, none
    around = ring / ring.sum()
    overlaps = np.minimum(counts / sizes[:, None], around).sum(axis=1)
    labels[top:bottom, left:right] = judged
    return labels, np.asarray(overlaps, np.float64)
