"""Pixels another tracked object hides: what an object behind leaves to the one in front.

When a session follows several objects (:class:`engine.tracking.ObjectsTracker`)
and two of them overlap, the one in front shows its own colours and edges over
the other.  Left alone, the object behind takes the front object's edge for its
own boundary and shrinks onto its visible part, its motion fit is outvoted by the
front object's points once more than half of it is covered, and it learns the
front object's colours as its own.  Told which pixels the objects in front of it
cover, a tracker makes its cue maps neutral there (p(object) 1/2, no edge, no
motion contrast), leaves the points there out of its motion and does not learn
from the frame: the chain carries the hidden part of the shape along with the
visible part, as under any occluder (the contour stays the object's whole
outline).

Which of two overlapping objects is in front is read from the frame: over the
pixels both silhouettes claim, the object whose appearance model finds them
more object-like shows there (:func:`in_front`).
Coordinates are ``[x, y]`` pixels (x = column, y = row), as in OpenCV.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from engine.geometry import any_in_frame, contour_to_mask
from engine.tracking.maps import Maps

__all__ = [
    "KEEP_ORDER",
    "NEUTRAL",
    "RIM",
    "Order",
    "RegionProbability",
    "Silhouette",
    "cover_maps",
    "covered_share",
    "fronts",
    "hidden_at",
    "in_front",
    "region_of",
]

NEUTRAL = 0.5
"""p(object) of a covered pixel: the colour there is another object's and says nothing."""
KEEP_ORDER = 0.1
"""Two overlapping objects change places only when the shared pixels look at least this
much more (mean p(object)) like the other one: objects of alike colours keep the order
found when their overlap began, and the one behind does not alternate frame by frame."""
RIM = 2
"""Pixels the front object's silhouette is grown by: its anti-aliased rim, whose mixed
colours and edge belong to it, and the 1-2 pixels its contour may be off."""


def region_of(
    covered: NDArray[np.bool_] | None, origin: tuple[int, int], shape: tuple[int, int]
) -> NDArray[np.bool_] | None:
    """The part of a frame-sized ``covered`` mask over a region (None: nothing covered there).

    ``origin`` is the region's top-left ``(x, y)`` in the frame and ``shape`` its
    ``(height, width)``.
    """
    if covered is None:
        return None
    x, y = origin
    h, w = shape
    part = covered[y : y + h, x : x + w]
    if part.shape != (h, w) or not part.any():
        return None
    return part


def hidden_at(covered: NDArray[np.bool_], points: NDArray[np.floating[Any]]) -> NDArray[np.bool_]:
    """``covered`` at the nearest pixel of each ``[x, y]`` point (clipped to the frame)."""
    h, w = covered.shape
    ij = np.clip(np.round(points).astype(np.int64), 0, [w - 1, h - 1])
    found: NDArray[np.bool_] = covered[ij[:, 1], ij[:, 0]]
    return found


def cover_maps(maps: Maps, covered: NDArray[np.bool_] | None) -> Maps:
    """``maps`` with the covered pixels neutral: p(object) 1/2, no edge, no motion contrast.

    ``covered`` is frame-sized (True where an object in front hides this one); the
    pixels' own look is kept as :attr:`Maps.observed`, what the confidence is read
    from, so a covered object is reported less sure of.
    """
    part = region_of(covered, maps.origin, maps.probability.shape)
    if part is None:
        return maps
    probability = maps.probability.copy()
    probability[part] = NEUTRAL
    if maps.edge_step == 1:
        edge_part = part
    else:  # edge pixel u covers pixels 2u and 2u + 1
        eh, ew = maps.edges.shape
        edge_part = part[: 2 * eh : 2, : 2 * ew : 2][:eh, :ew]
        padded = np.zeros((eh, ew), np.bool_)
        padded[: edge_part.shape[0], : edge_part.shape[1]] = edge_part
        edge_part = padded
    edges = maps.edges.copy()
    edges[edge_part] = 0.0
    motion = maps.motion
    if motion is not None:
        motion = motion.copy()
        motion[part] = 1.0
    return dataclasses.replace(
        maps, probability=probability, edges=edges, observed=maps.seen, motion=motion
    )


def covered_share(covered: NDArray[np.bool_] | None, nodes: NDArray[np.float64]) -> float:
    """Share of the silhouette of the closed contour ``nodes`` (``[x, y]``) that the
    frame-sized ``covered`` hides (0 without a mask)."""
    if covered is None:
        return 0.0
    h, w = covered.shape
    x0, y0 = np.clip(np.floor(nodes.min(axis=0)).astype(int), 0, [w, h])
    x1, y1 = np.clip(np.ceil(nodes.max(axis=0)).astype(int) + 1, 0, [w, h])
    inside = contour_to_mask(nodes - [x0, y0], (y1 - y0, x1 - x0)) > 0
    total = int(np.count_nonzero(inside))
    hidden = np.count_nonzero(covered[y0:y1, x0:x1] & inside)
    return float(hidden) / total if total else 0.0


def in_front(
    a: NDArray[np.float32],
    b: NDArray[np.float32],
    overlap: NDArray[np.bool_],
    was: bool | None = None,
) -> bool | None:
    """Whether object ``a`` is in front of ``b`` where their silhouettes overlap.

    ``a`` and ``b`` are their appearance models' p(object) over one region of the
    current frame and ``overlap`` the region's pixels both silhouettes claim: the
    object those pixels look more like shows there.  ``was``: the answer of the last
    frame, kept unless the pixels look at least :data:`KEEP_ORDER` more like the other
    object.  None when the overlap is empty.
    """
    if not overlap.any():
        return None
    lead = float(a[overlap].mean()) - float(b[overlap].mean())
    if was is not None and abs(lead) < KEEP_ORDER:
        return was
    return lead >= 0


@dataclass(frozen=True, slots=True)
class Silhouette:
    """An object's silhouette grown by :data:`RIM`, over its box in the frame.

    Attributes
    ----------
    box : tuple of int
        ``(x0, y0, x1, y1)``: the mask covers columns x0..x1-1 and rows y0..y1-1.
    mask : numpy.ndarray
        (y1 - y0, x1 - x0) bool.
    """

    box: tuple[int, int, int, int]
    mask: NDArray[np.bool_]

    @classmethod
    def of(
        cls, contours: Sequence[NDArray[np.float64]], shape: tuple[int, int]
    ) -> Silhouette | None:
        """The silhouette of closed ``[x, y]`` contours (an object's pieces) in a frame of
        ``shape`` (height, width); None when it misses the frame, or none of its nodes lies
        in it: a contour around the whole frame shows none of its boundary, and its tracker
        reports it lost (confidence 0), not in front of every other object."""
        points = np.vstack(contours)
        h, w = shape
        if not any_in_frame(points, shape):
            return None
        x0, y0 = np.clip(np.floor(points.min(axis=0)).astype(int) - RIM, 0, [w, h])
        x1, y1 = np.clip(np.ceil(points.max(axis=0)).astype(int) + RIM + 1, 0, [w, h])
        if x1 <= x0 or y1 <= y0:
            return None
        inside = np.zeros((y1 - y0, x1 - x0), np.uint8)
        for contour in contours:
            inside |= contour_to_mask(contour - [x0, y0], inside.shape)
        kernel = np.ones((2 * RIM + 1, 2 * RIM + 1), np.uint8)
        mask = np.asarray(cv2.dilate(inside, kernel), np.uint8) > 0
        if not mask.any():
            return None
        return cls((int(x0), int(y0), int(x1), int(y1)), mask)

    def paint(self, covered: NDArray[np.bool_]) -> None:
        """Set this silhouette's pixels in a frame-sized mask."""
        x0, y0, x1, y1 = self.box
        covered[y0:y1, x0:x1] |= self.mask

    def overlap(
        self, other: Silhouette
    ) -> tuple[tuple[int, int, int, int], NDArray[np.bool_]] | None:
        """The box both silhouettes' boxes share and where both claim its pixels (None: nowhere)."""
        x0, y0 = max(self.box[0], other.box[0]), max(self.box[1], other.box[1])
        x1, y1 = min(self.box[2], other.box[2]), min(self.box[3], other.box[3])
        if x1 <= x0 or y1 <= y0:
            return None
        both = self._part(x0, y0, x1, y1) & other._part(x0, y0, x1, y1)
        return ((x0, y0, x1, y1), both) if both.any() else None

    def _part(self, x0: int, y0: int, x1: int, y1: int) -> NDArray[np.bool_]:
        bx, by = self.box[:2]
        return self.mask[y0 - by : y1 - by, x0 - bx : x1 - bx]


RegionProbability = Callable[[Hashable, tuple[int, int, int, int]], NDArray[np.float32]]
"""An object's appearance p(object) over a box ``(x0, y0, x1, y1)`` of the current frame."""


Order = dict[frozenset[Hashable], Hashable]
"""Each overlapping pair of objects (their ids) -> the id of the one in front."""


def fronts(
    silhouettes: Mapping[Hashable, Silhouette],
    probability: RegionProbability,
    order: Order | None = None,
) -> tuple[dict[Hashable, list[Hashable]], Order]:
    """For each object, the objects in front of it (:func:`in_front`), in the mapping's
    order; and the order of each overlapping pair, for the next frame.

    Every pair of overlapping silhouettes is decided once, from the pixels both claim,
    keeping ``order`` (the last frame's) unless the pixels clearly say otherwise; a pair
    that no longer overlaps is forgotten.
    """
    found: dict[Hashable, list[Hashable]] = {key: [] for key in silhouettes}
    decided: Order = {}
    keys = list(silhouettes)
    for i, a in enumerate(keys):
        for b in keys[i + 1 :]:
            shared = silhouettes[a].overlap(silhouettes[b])
            if shared is None:
                continue
            box, both = shared
            pair = frozenset((a, b))
            before = (order or {}).get(pair)
            was = None if before is None else before == a
            a_first = in_front(probability(a, box), probability(b, box), both, was)
            front, back = (a, b) if a_first else (b, a)
            found[back].append(front)
            decided[pair] = front
    return found, decided
